"""The compiled parts of segadeform: the collision kernel ``src/segadeform/body/_collide.c`` and the cloth stage
``src/segadeform/body/_cloth.c`` (built with the collision kernel it calls).

Everything else is declared in ``pyproject.toml``.  Each kernel is plain C99 built as an (empty)
extension module (``segadeform.body._collide``, ``segadeform.body._cloth``) and called through ctypes; both are
optional: without a C compiler the install goes on, :class:`segadeform.body.collision.BodyCollider` falls back to
its numpy implementation (with one logged warning) and the cloth stage says it needs the compiled kernel.
"""

import sys

from setuptools import Extension, setup

if sys.platform == "win32":
    FLAGS = ["/O2", "/fp:precise"]
else:
    # no floating-point contraction (fused multiply-add would round differently per platform); the file is
    # C99 (tests/body/test_collision_compiled.py compiles it with -std=c99 -pedantic), but Python.h, included
    # for the module stub, may need the compiler's default standard
    FLAGS = ["-O2", "-ffp-contract=off"]

setup(
    ext_modules=[
        Extension(
            "segadeform.body._collide",
            sources=["src/segadeform/body/_collide.c"],
            define_macros=[("SDC_PYTHON_MODULE", "1")],
            extra_compile_args=FLAGS,
            optional=True,
        ),
        # the cloth stage (segadeform.body.cloth): _cloth.c with the collider it calls, in one library
        Extension(
            "segadeform.body._cloth",
            sources=["src/segadeform/body/_cloth.c", "src/segadeform/body/_collide.c"],
            define_macros=[("SCL_PYTHON_MODULE", "1")],
            extra_compile_args=FLAGS,
            optional=True,
        ),
    ]
)
