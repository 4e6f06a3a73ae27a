#!/usr/bin/env bash
# Installs the baselines benchmarks/bench_vs_pyrender.py compares softrast with, all on Mesa's
# llvmpipe (the CPU path of every GL-based Python renderer):
#   pyrender 0.1.45 through OSMesa (PYOPENGL_PLATFORM=osmesa, no anti-aliasing),
#   moderngl through a standalone EGL context (EGL_PLATFORM=surfaceless, no display needed),
#   valgrind for bench_stages.py --callgrind.
# Idempotent: installs only what is missing; exits non-zero naming what failed.
# Usage: bash benchmarks/setup_baselines.sh [PYTHON]   (default: python3)
set -euo pipefail

PY="${1:-python3}"
fail() { echo "setup_baselines: $*" >&2; exit 1; }

# Debian: OSMesa for pyrender; libGL/GLU (pyrender's PyOpenGL imports GLU); EGL + the Mesa DRI
# drivers (llvmpipe lives in libgl1-mesa-dri / swrast) for moderngl's surfaceless EGL context.
debs=(libosmesa6 libgl1 libglu1-mesa libegl1 libegl-mesa0 libgl1-mesa-dri valgrind g++)
missing=()
for p in "${debs[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if ((${#missing[@]})); then
  command -v apt-get >/dev/null || fail "apt-get not found; install Debian packages ${missing[*]} by hand"
  SUDO=""; [ "$(id -u)" -ne 0 ] && SUDO="sudo"
  echo "setup_baselines: apt-get install ${missing[*]}"
  $SUDO apt-get update -qq || fail "apt-get update failed"
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}" \
    || fail "apt-get install ${missing[*]} failed"
fi

pip_has() { "$PY" -m pip show "$1" 2>/dev/null | grep -q "^Version: $2"; }
# pyrender pins PyOpenGL==3.1.0, which fails with current NumPy and OSMesa; 3.1.10 works, so
# install pyrender first, then upgrade PyOpenGL over its pin (pip warns about the pin: expected).
pip_has pyrender 0.1.45 || "$PY" -m pip install -q "pyrender==0.1.45" || fail "pip install pyrender==0.1.45 failed"
"$PY" - <<'EOF' || "$PY" -m pip install -q "PyOpenGL>=3.1.10" || fail "pip install PyOpenGL>=3.1.10 failed"
import importlib.metadata as md, sys
v = tuple(int(x) for x in md.version("PyOpenGL").split(".")[:3])
sys.exit(0 if v >= (3, 1, 10) else 1)
EOF
"$PY" -c "import moderngl" 2>/dev/null || "$PY" -m pip install -q moderngl || fail "pip install moderngl failed"

# Smoke test: both baselines must open a context and draw on this machine.
PYOPENGL_PLATFORM=osmesa "$PY" - <<'EOF' || fail "pyrender/OSMesa smoke test failed (see above)"
import numpy as np, pyrender, trimesh
scene = pyrender.Scene()
scene.add(pyrender.Mesh.from_trimesh(trimesh.creation.icosphere(1)))
scene.add(pyrender.PerspectiveCamera(yfov=0.8), pose=np.array(
    [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 3], [0, 0, 0, 1]], float))
r = pyrender.OffscreenRenderer(32, 32)
color, depth = r.render(scene)
assert depth.max() > 0, "pyrender drew nothing"
r.delete()
print("setup_baselines: pyrender", pyrender.__version__, "via OSMesa OK")
EOF
EGL_PLATFORM=surfaceless "$PY" - <<'EOF' || fail "moderngl/EGL smoke test failed (see above)"
import moderngl
ctx = moderngl.create_standalone_context(backend="egl")
print("setup_baselines: moderngl", moderngl.__version__, "EGL OK:", ctx.info["GL_RENDERER"])
ctx.release()
EOF
echo "setup_baselines: all baselines ready"
