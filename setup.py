"""The one compiled part of segadeform: the collision kernel ``src/segadeform/body/_collide.c``.

Everything else is declared in ``pyproject.toml``.  The kernel is a plain C99 file built as the (empty)
extension module ``segadeform.body._collide`` and called through ctypes; it is optional: without a C
compiler the install goes on and :class:`segadeform.body.collision.BodyCollider` falls back to its numpy
implementation (with one logged warning).
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

setup(ext_modules=[Extension("segadeform.body._collide", sources=["src/segadeform/body/_collide.c"],
                             define_macros=[("SDC_PYTHON_MODULE", "1")], extra_compile_args=FLAGS,
                             optional=True)])
