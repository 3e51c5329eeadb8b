"""Builds the viscd extension with CMake for `pip install .` and `pip wheel .` (pyproject.toml).

setuptools runs this through its build backend; nobody calls it directly. It configures the
project's CMake build for the interpreter that runs pip (so a virtual environment, pyenv or conda
Python gets a module of its own), builds the one target `viscd_python` (the C++ library and the
pybind11 extension), and hands the extension to setuptools, which packs it with python/viscd/
(the pure-Python part, its type stub, py.typed) and the licence.

Environment (read by this build script only; the library reads none):
  VISCD_BUILD_DIR    the CMake build folder (default build/pip-<python tag> in the checkout; an
                     existing folder is built incrementally)
  VISCD_CMAKE_ARGS   extra arguments for the configure step, e.g. "-DVISCD_ENABLE_CUDA=OFF"
"""

import os
import re
import shlex
import shutil
import subprocess
import sys
import sysconfig
from pathlib import Path

from setuptools import Extension, setup
from setuptools.command.build_ext import build_ext

ROOT = Path(__file__).resolve().parent


def project_version() -> str:
    """The version in CMakeLists.txt's project(), which include/viscd/version.hpp repeats."""
    text = (ROOT / "CMakeLists.txt").read_text()
    match = re.search(r"project\(viscd VERSION (\d+\.\d+\.\d+)", text)
    if not match:
        sys.exit("setup.py: no 'project(viscd VERSION x.y.z' in CMakeLists.txt")
    return match.group(1)


class CMakeExtension(Extension):
    def __init__(self) -> None:
        super().__init__("viscd._viscd", sources=[])


class CMakeBuild(build_ext):
    def build_extension(self, ext: Extension) -> None:
        if shutil.which("cmake") is None:
            sys.exit("setup.py: cmake not found (Debian: apt-get install cmake; scripts/setup.sh installs "
                     "everything the build needs)")
        tag = f"py{sys.version_info.major}{sys.version_info.minor}"
        build_dir = Path(os.environ.get("VISCD_BUILD_DIR") or ROOT / "build" / f"pip-{tag}")
        configure = [
            "cmake", "-S", str(ROOT), "-B", str(build_dir),
            "-DCMAKE_BUILD_TYPE=Release",
            f"-DPython3_EXECUTABLE={sys.executable}",
            "-DVISCD_BUILD_PYTHON=ON",
            "-DVISCD_BUILD_TESTS=OFF", "-DVISCD_BUILD_APPS=OFF", "-DVISCD_BUILD_BENCH=OFF",
            "-DVISCD_BUILD_VIEWER=OFF", "-DVISCD_BUILD_ADAPTERS=OFF",
            # Sources compiled eight to a file: a fresh install builds in less time (CONTRIBUTING.md).
            "-DCMAKE_UNITY_BUILD=ON",
        ]
        configure += shlex.split(os.environ.get("VISCD_CMAKE_ARGS", ""))
        jobs = str(os.cpu_count() or 2)
        self._run(configure)
        # viscd._viscd_mpi (DistributedDetector) comes along where CMake found MPI and mpi4py.
        cache = (build_dir / "CMakeCache.txt").read_text()
        targets = ["viscd_python"] + (["viscd_python_mpi"] if "VISCD_PYTHON_MPI:INTERNAL=ON" in cache else [])
        self._run(["cmake", "--build", str(build_dir), "--target", *targets, "--parallel", jobs])
        suffix = sysconfig.get_config_var("EXT_SUFFIX") or ".so"
        built = build_dir / "python" / "viscd" / f"_viscd{suffix}"
        if not built.exists():
            sys.exit(f"setup.py: the build made no {built} (is NumPy importable by {sys.executable}? "
                     "CMake's output above says why the module was disabled)")
        dest = Path(self.get_ext_fullpath(ext.name))
        dest.parent.mkdir(parents=True, exist_ok=True)
        shutil.copy2(built, dest)
        mpi_module = dest.with_name(f"_viscd_mpi{suffix}")
        if "viscd_python_mpi" in targets:
            shutil.copy2(built.with_name(f"_viscd_mpi{suffix}"), mpi_module)
        elif mpi_module.exists():
            mpi_module.unlink()  # from an earlier build with MPI: it would ship stale

    @staticmethod
    def _run(command: list) -> None:
        print("setup.py:", " ".join(shlex.quote(c) for c in command), flush=True)
        subprocess.check_call(command)


setup(
    version=project_version(),
    ext_modules=[CMakeExtension()],
    cmdclass={"build_ext": CMakeBuild},
    zip_safe=False,
)
