#!/usr/bin/env bash
# The GPU benchmark, one script (under 8 minutes): check that EGL runs on the vendor's driver, then time
# every technique at 1920x1080 for 1M, 10M and 50M splats (benchmarks/bench_gpu.py) and the peers where
# they are installed, and write benchmarks/results/gpu.md (and gpu_peers.md).
#
#   bash benchmarks/gpu.sh --fetch-wheels   # on a machine with PyPI: the wheels a machine without it needs
#   bash benchmarks/gpu.sh                  # on the GPU machine, from the repository's root
#
# A GPU machine without PyPI installs surfsplat's dependencies from .gpu-wheels/ (made by --fetch-wheels
# for CPython 3.12 on x86-64 Linux, or GPU_PYTHON_VERSION). Debian's GL loaders unpacked into .gl/ (libegl1,
# libglvnd0, libopengl0, libgl1, libglx0) are installed first where that folder exists.
set -euo pipefail
cd "$(dirname "$0")/.."
PYTHON="${PYTHON:-python3}"
WHEELS=.gpu-wheels

if [[ "${1:-}" == "--fetch-wheels" ]]; then
    version="${GPU_PYTHON_VERSION:-3.12}"
    mkdir -p "$WHEELS"
    "$PYTHON" -m pip download --quiet --dest "$WHEELS" --only-binary=:all: --python-version "$version" \
        --platform manylinux2014_x86_64 --platform manylinux_2_17_x86_64 --platform manylinux_2_28_x86_64 \
        moderngl glcontext plyfile trimesh networkx pypng tqdm
    ls "$WHEELS"
    exit 0
fi

if compgen -G ".gl/*.deb" >/dev/null; then
    for f in .gl/*.deb; do dpkg -x "$f" /; done
    ldconfig
fi
if ! "$PYTHON" -c "import moderngl, plyfile, trimesh" 2>/dev/null; then
    if [[ -d "$WHEELS" ]]; then
        "$PYTHON" -m pip install --quiet --no-index --find-links "$WHEELS" moderngl glcontext plyfile trimesh \
            networkx pypng tqdm
    else
        "$PYTHON" -m pip install --quiet -e .
    fi
fi
export PYTHONPATH="$PWD/src${PYTHONPATH:+:$PYTHONPATH}"
# The vendor's EGL, where the driver's files are mounted in the usual place of a container.
if [[ -z "${__EGL_VENDOR_LIBRARY_FILENAMES:-}" && -f /usr/local/nvidia/share/glvnd/egl_vendor.d/10_nvidia.json ]]; then
    export __EGL_VENDOR_LIBRARY_FILENAMES=/usr/local/nvidia/share/glvnd/egl_vendor.d/10_nvidia.json
fi

echo "== EGL"
"$PYTHON" - <<'EOF'
import sys
import moderngl
ctx = moderngl.create_standalone_context(require=330, backend="egl")
name = f"{ctx.info['GL_RENDERER']} ({ctx.info['GL_VERSION']})"
print("GL:", name)
if any(word in name.lower() for word in ("llvmpipe", "softpipe", "swiftshader")):
    sys.exit("gpu.sh: EGL gave a software rasterizer, not the GPU's driver")
EOF

echo "== surfsplat, every technique, 1920x1080"
timeout 420 "$PYTHON" -u benchmarks/bench_gpu.py --sizes 1000000 10000000 50000000 --width 1920 --height 1080 \
    --repeat 5 --name gpu

echo "== peers"
if "$PYTHON" -c "import pyvista" 2>/dev/null && [[ -d ../shared/peers ]]; then
    timeout 120 "$PYTHON" ../shared/peers/bench.py --work /tmp/peers-data --sizes 1000000 --repeat 3 \
        --width 1920 --height 1080 --only vtk_points,vtk_disks \
        --add "surfsplat_ewa=$PYTHON ../shared/peers/render_surfsplat.py --technique ewa" \
        | tee benchmarks/results/gpu_peers.md
else
    echo "the peers (VTK through pyvista, ../shared/peers) are not installed here: skipped"
fi
