"""Builds the compiled part of the hpcm Python package (hpcm._hpcm) with the project's CMake.

pyproject.toml holds the metadata; this file only adds the CMake step, because Debian 12
packages setuptools but no CMake-aware build backend. Environment:
  HPCM_BUILD_DIR   an already configured CMake build folder to reuse: only its hpcm_python
                   target is (re)built, which takes seconds when it is up to date
  HPCM_CMAKE_ARGS  extra arguments for a fresh configure (e.g. "-DHPCM_CUDA=OFF")
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

SOURCE_DIR = Path(__file__).resolve().parent


def project_version():
    """The one version definition: project(hpcm VERSION x.y.z) in CMakeLists.txt."""
    text = (SOURCE_DIR / "CMakeLists.txt").read_text()
    match = re.search(r"project\(\s*hpcm\s+VERSION\s+([0-9]+(?:\.[0-9]+)*)", text)
    if not match:
        raise RuntimeError(f"{SOURCE_DIR / 'CMakeLists.txt'}: no 'project(hpcm VERSION x.y.z)' found")
    return match.group(1)


class CMakeExtension(Extension):
    """An extension that CMake builds (no sources for setuptools to compile)."""

    def __init__(self, name):
        super().__init__(name, sources=[])


class CMakeBuild(build_ext):
    """Builds the CMake target hpcm_python and copies the module into the package."""

    def build_extension(self, ext):
        build_dir = self._cmake_build_dir()
        jobs = os.environ.get("CMAKE_BUILD_PARALLEL_LEVEL") or str(os.cpu_count() or 1)
        self._run(["cmake", "--build", str(build_dir), "--target", "hpcm_python", "--parallel", jobs])
        built = build_dir / "python" / "hpcm" / ("_hpcm" + sysconfig.get_config_var("EXT_SUFFIX"))
        if not built.is_file():
            raise SystemExit(
                f"hpcm: {built} was not built. Either CMake skipped the Python module (its output above "
                f"says why: pybind11-dev or python3-dev missing) or {build_dir} builds it for another "
                f"Python than {sys.executable} (HPCM_PYTHON_EXECUTABLE in its CMakeCache.txt)")
        target = Path(self.get_ext_fullpath(ext.name))
        target.parent.mkdir(parents=True, exist_ok=True)
        shutil.copy2(built, target)

    def _cmake_build_dir(self):
        reuse = os.environ.get("HPCM_BUILD_DIR")
        if reuse:
            build_dir = Path(reuse).resolve()
            if not (build_dir / "CMakeCache.txt").is_file():
                raise SystemExit(f"hpcm: HPCM_BUILD_DIR={reuse}: not a configured CMake build folder "
                                 f"(no CMakeCache.txt); configure it first: cmake -S . -B {reuse}")
            return build_dir  # its configuration is the user's: reconfiguring would change it
        build_dir = Path(self.build_temp).resolve() / "cmake"
        self._run(["cmake", "-S", str(SOURCE_DIR), "-B", str(build_dir),
                   "-DCMAKE_BUILD_TYPE=Release",
                   f"-DHPCM_PYTHON_EXECUTABLE={sys.executable}",
                   # Only the module is needed: no tests, benchmarks, CLI or viewer.
                   "-DHPCM_BUILD_TESTS=OFF", "-DHPCM_BUILD_BENCH=OFF",
                   "-DHPCM_BUILD_APPS=OFF", "-DHPCM_BUILD_VIEWER=OFF",
                   *shlex.split(os.environ.get("HPCM_CMAKE_ARGS", ""))])
        return build_dir

    @staticmethod
    def _run(argv):
        print("hpcm:", " ".join(argv), flush=True)
        subprocess.run(argv, check=True)


setup(
    version=project_version(),
    ext_modules=[CMakeExtension("hpcm._hpcm")],
    cmdclass={"build_ext": CMakeBuild},
    # Not build/: that is where the CMake build of the project usually lives.
    options={"build": {"build_base": "build-py"}},
)
