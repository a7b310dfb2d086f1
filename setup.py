"""Build switchest's engine: the C kernels of ``src/switchest/engine/c`` behind their Cython
bindings (``src/switchest/engine/_*.pyx``), one extension module per family of filters.

Each binding names its family's C file in its ``# distutils: sources`` line; the files
several families share (``linalg.c``, the shared equations, and ``bank.c``, the IMM/GPB bank)
are compiled once, into a static library every module links (compiled once per module, the
parallel build wrote the same object file from two threads at once). The kernels are compiled with ``-O3`` for the building machine's processor (``-march=native``), as
a source install runs where it was built; set ``SWITCHEST_PORTABLE=1`` to build for the
architecture's baseline instead, for a wheel meant to run on other machines. Floating-point
contraction stays off (``-ffp-contract=off``): each product and sum is rounded as written, as
in the numpy oracles the tests compare against. The modules compile side by side, one per
core.
"""

import os
import subprocess
from pathlib import Path

import numpy
from Cython.Build import cythonize
from setuptools import Extension, setup
from setuptools.command.build_py import build_py

ENGINE = Path("src/switchest/engine")
PORTABLE = os.environ.get("SWITCHEST_PORTABLE", "0") not in ("", "0")
FLAGS = ["-O3", "-std=c11", "-D_DEFAULT_SOURCE", "-fno-math-errno", "-ffp-contract=off"]
if not PORTABLE:
    FLAGS.append("-march=native")
# libm linked by name, at the end of the link (after the static library that calls it): the
# modules call its log and exp; unlinked, those stayed unversioned, bound at load time to
# whichever libm the process had, and to glibc's oldest versions of them
LINK = ["-lm"] if os.name == "posix" else []

SHARED = ["linalg.c", "bank.c"]  # the C files of several families: one static library
engine_library = ("switchest_engine", {
    "sources": [str(ENGINE / "c" / name) for name in SHARED],
    "include_dirs": [str(ENGINE / "c")],
    "cflags": [*FLAGS, "-fPIC"],  # linked into shared modules
    # a header edit rebuilds the library too: its static inline functions are in the headers
    "obj_deps": {"": [str(path) for path in sorted((ENGINE / "c").glob("*.h"))]},
})

extensions = [
    Extension(
        f"switchest.engine.{pyx.stem}",
        [str(pyx)],
        include_dirs=[str(ENGINE / "c"), numpy.get_include()],
        depends=[str(path) for path in sorted((ENGINE / "c").glob("*.[ch]"))]  # a header edit
        + [str(ENGINE / "_common.pxd")],  # rebuilds too
        define_macros=[("NPY_NO_DEPRECATED_API", "NPY_1_7_API_VERSION")],
        extra_compile_args=FLAGS,
        extra_link_args=LINK,
    )
    for pyx in sorted(ENGINE.glob("_*.pyx"))
]



class build_py_with_commit(build_py):
    """Also write ``switchest/_commit.txt``: the git commit the package is built from (``+
    uncommitted changes`` when the tree has any), which the report's provenance reads from the
    installed package wherever it is installed."""

    def run(self):
        super().run()
        if self.dry_run:
            return
        target = Path(self.build_lib) / "switchest" / "_commit.txt"
        target.parent.mkdir(parents=True, exist_ok=True)
        target.write_text(_source_commit() + "\n", encoding="utf-8")


def _source_commit() -> str:
    try:
        head = subprocess.run(["git", "rev-parse", "--short=12", "HEAD"], capture_output=True,
                              text=True, timeout=10)
        dirty = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no", "--",
                                "src"], capture_output=True, text=True, timeout=10)
    except (OSError, subprocess.SubprocessError):
        return "unknown (built without git)"
    if head.returncode != 0:
        return "unknown (built outside a git checkout)"
    return head.stdout.strip() + (" + uncommitted changes" if dirty.stdout.strip() else "")


setup(
    cmdclass={"build_py": build_py_with_commit},
    libraries=[engine_library],
    options={"build_ext": {"parallel": os.cpu_count() or 1}},  # the families side by side
    ext_modules=cythonize(
        extensions,
        compiler_directives={
            "language_level": 3,
            "boundscheck": False,
            "wraparound": False,
            "initializedcheck": False,
            "cdivision": True,
        },
        include_path=["src"],
        nthreads=os.cpu_count() or 1,
    ),
)
