"""Mesh files: what they carry and how softrast reads it (the rules: docs/file_formats.md).

``load.py``        ``load_mesh`` and ``load_scene`` (re-exported by ``softrast``)
``checks.py``      PLY, OFF, OBJ and STL checked against their own counts before parsing
``gltf_file.py``   a .gltf or .glb read once, checked, and handed to trimesh
``gltf.py``        glTF materials, textures and samplers, read exactly from the JSON
``mtl.py``         OBJ + MTL materials, read from the MTL file
``images.py``      images carried or named by a file, as Textures
``convert.py``     trimesh objects -> arrays and Materials (the parts Mesh and Scene are made of)
``context.py``     what one load knows (the file, its colour convention, its materials)

This package's ``__init__`` imports nothing, so ``softrast.mesh`` can use ``convert`` while
``load`` uses ``softrast.mesh``.
"""
