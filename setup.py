"""Builds the rangebayes Python module with the project's CMake build (no download) and packages it.

`pip install --no-build-isolation .` runs this. The C++ build folder is build/pip (override with
RANGEBAYES_BUILD_DIR, e.g. an existing build/release); extra CMake arguments come from RANGEBAYES_CMAKE_ARGS.
"""

import os
import pathlib
import shlex
import shutil
import subprocess
import sys

from setuptools import Extension, setup
from setuptools.command.build_ext import build_ext

ROOT = pathlib.Path(__file__).resolve().parent


class CMakeBuild(build_ext):
    def build_extension(self, ext):
        build_dir = pathlib.Path(os.environ.get("RANGEBAYES_BUILD_DIR", ROOT / "build" / "pip"))
        if not build_dir.is_absolute():
            build_dir = ROOT / build_dir
        if not (build_dir / "CMakeCache.txt").exists():
            args = ["cmake", "-S", str(ROOT), "-B", str(build_dir), "-G", "Ninja", "-DCMAKE_BUILD_TYPE=Release",
                    f"-DPython3_EXECUTABLE={sys.executable}", "-DRANGEBAYES_BUILD_PYTHON=ON",
                    "-DRANGEBAYES_BUILD_TESTS=OFF", "-DRANGEBAYES_BUILD_BENCH=OFF"]
            args += shlex.split(os.environ.get("RANGEBAYES_CMAKE_ARGS", ""))
            subprocess.run(args, check=True)
        jobs = os.environ.get("CMAKE_BUILD_PARALLEL_LEVEL", "2")
        subprocess.run(["cmake", "--build", str(build_dir), "--target", "_rangebayes", "-j", jobs], check=True)
        built = next((build_dir / "python" / "rangebayes").glob("_rangebayes*.so"))
        target = pathlib.Path(self.get_ext_fullpath(ext.name))
        target.parent.mkdir(parents=True, exist_ok=True)
        shutil.copy2(built, target)


setup(
    ext_modules=[Extension("rangebayes._rangebayes", sources=[])],
    cmdclass={"build_ext": CMakeBuild},
    package_data={"rangebayes": ["__init__.pyi", "py.typed"]},
)
