"""Instructions per render call, whole process, counted by callgrind (repeatable on a noisy
machine, unlike a clock): run this script under valgrind with N = 0 and N = 300 and divide the
difference by 2 N (each round makes two calls: depth alone, and colour + depth with keyword
options). The call is an icosphere of subdivision 3 into a 1x1 image, so the count is the Python
layer's and the binding's fixed cost per call, plus a one-pixel frame.

    PY=$(python3 -c 'import sys; print(sys.executable)')
    valgrind --tool=callgrind --callgrind-out-file=/tmp/cg.0 $PY benchmarks/count_call_instructions.py 0
    valgrind --tool=callgrind --callgrind-out-file=/tmp/cg.300 $PY benchmarks/count_call_instructions.py 300

(``Collected`` in valgrind's last lines; PYTHONPATH selects the softrast to count.)
"""
import sys

import numpy as np
import trimesh

import softrast as sr

m = trimesh.creation.icosphere(subdivisions=3)
scene = sr.Scene()
scene.add(sr.Mesh(np.asarray(m.vertices), np.asarray(m.faces)))
cam = sr.PerspectiveCamera(fov_y=40.0)
cam.pose = sr.look_at_pose((0, 0, 4), (0, 0, 0))
r1 = sr.Renderer(1, 1, threads=1)
for _ in range(50):  # warm: caches, imports done
    r1.render(scene, cam, ("depth",))
    r1.render(scene, cam, ("color", "depth"), msaa=1, background=(0.1, 0.2, 0.3))
for _ in range(int(sys.argv[1]) if len(sys.argv) > 1 else 0):
    r1.render(scene, cam, ("depth",))
    r1.render(scene, cam, ("color", "depth"), msaa=1, background=(0.1, 0.2, 0.3))
