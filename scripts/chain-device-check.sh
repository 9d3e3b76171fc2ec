for f in .gl/*.deb; do dpkg -x "$f" /; done; ldconfig
python3 -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --target /tmp/site .whl/*.whl || exit 3
export PYTHONPATH=/tmp/site:$PWD/src PYTHONUNBUFFERED=1
[ -f /usr/local/nvidia/share/glvnd/egl_vendor.d/10_nvidia.json ] && export __EGL_VENDOR_LIBRARY_FILENAMES=/usr/local/nvidia/share/glvnd/egl_vendor.d/10_nvidia.json
python3 -c "import dermis, moderngl; from dermis.renderer import Renderer; print(dermis.__file__)"
timeout 150 python3 -m pytest tests/test_tsd_numeric.py tests/test_realtime.py -q -x -p no:cacheprovider 2>&1 | tail -5
REPS=9 VARIANTS='[{"NARROW_PASS": false, "LEVEL_LIGHT_WEIGHT": 0.0, "TAP_REACH_SIGMAS": 3.0}, {}]' timeout 120 python3 benchmarks/chain_variants.py 2>&1 | tail -4
