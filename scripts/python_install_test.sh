#!/usr/bin/env bash
# The Python module as users install it (docs/python.md, "Installing"): pip builds it from this
# checkout, offline, into a fresh virtual environment that sees Debian's NumPy, SciPy and pytest
# (--system-site-packages), and the pytest suite runs against that install from a folder outside
# the checkout. Then `pip wheel .` makes a wheel, whose contents are checked. scripts/test.sh runs
# this after ctest (release preset). The build folder is build/pip-py3X (kept between runs). The
# cuda backend and viscd.DistributedDetector (MPI) are left out of this install unless
# VISCD_CMAKE_ARGS says otherwise: they add minutes to a fresh build, and the build tree's module
# has both (ctest's python.pytest and mpi.python1/3). With
# VISCD_CMAKE_ARGS="-DVISCD_ENABLE_CUDA=OFF -DVISCD_ENABLE_MPI=ON" the installed DistributedDetector
# is tested under mpirun -np 2 too (name both: the build folder's cache keeps the last values).
# Usage: scripts/python_install_test.sh
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
py=/usr/bin/python3  # Debian's, which has NumPy; the venv is made from it
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT

echo "python: a virtual environment in $work"
"$py" -m venv --system-site-packages "$work/venv"
vpy="$work/venv/bin/python"
export VISCD_CMAKE_ARGS="${VISCD_CMAKE_ARGS:--DVISCD_ENABLE_CUDA=OFF -DVISCD_ENABLE_MPI=OFF}"
echo "python: pip install --no-build-isolation $root (VISCD_CMAKE_ARGS=$VISCD_CMAKE_ARGS)"
"$vpy" -m pip install --no-build-isolation --no-index --quiet "$root"

cd "$work"  # outside the checkout: the installed module, not python/ of the checkout
"$vpy" - <<'PY'
import importlib.metadata as metadata
import pathlib
import sys

import viscd

where = pathlib.Path(viscd.__file__).resolve()
assert pathlib.Path(sys.prefix).resolve() in where.parents, f"viscd imported from {where}, not the venv"
assert viscd.__version__ == metadata.version("viscd"), (viscd.__version__, metadata.version("viscd"))
files = {str(f) for f in metadata.files("viscd")}
for needed in ("viscd/__init__.py", "viscd/__init__.pyi", "viscd/py.typed"):
    assert needed in files, f"{needed} is not installed"
assert any(f.startswith("viscd/_viscd") for f in files), "the extension is not installed"
assert any(f.endswith("LICENSE") for f in files), "the licence is not installed"
assert metadata.metadata("viscd")["License"] == "MIT"
print(f"python: viscd {viscd.__version__} installed at {where.parent}")
PY
"$vpy" -m pytest -q -p no:cacheprovider "$root/tests/python"
# viscd.DistributedDetector from the install, on two ranks, where MPI and mpi4py were there to build it.
if "$vpy" -c "import viscd._viscd_mpi" 2>/dev/null && command -v mpirun >/dev/null; then
  echo "python: the installed DistributedDetector under mpirun -np 2"
  OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1 OMPI_MCA_rmaps_base_oversubscribe=1 \
    mpirun -np 2 "$vpy" -m pytest -q -p no:cacheprovider "$root/tests/python_mpi"
else
  echo "python: no viscd._viscd_mpi in this install (MPI or mpi4py missing): DistributedDetector not tested here"
fi

echo "python: pip wheel --no-build-isolation $root"
"$vpy" -m pip wheel --no-build-isolation --no-index --no-deps --quiet -w "$work/wheel" "$root"
"$vpy" - "$work"/wheel/viscd-*.whl <<'PY'
import sys
import zipfile

names = zipfile.ZipFile(sys.argv[1]).namelist()
for needed in ("viscd/__init__.py", "viscd/__init__.pyi", "viscd/py.typed"):
    assert needed in names, f"{needed} is not in the wheel"
assert any(n.startswith("viscd/_viscd") for n in names), "the extension is not in the wheel"
assert any(n.endswith(".dist-info/LICENSE") for n in names), "the licence is not in the wheel"
print(f"python: {sys.argv[1].rsplit('/', 1)[-1]}: {len(names)} files")
PY
echo "python: install, tests and wheel ok"
