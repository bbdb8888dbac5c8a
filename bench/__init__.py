"""Benchmarks (scripts: ``.venv/bin/python bench/NAME.py``).  A package only so that the reusable parts of a
benchmark can be imported from the repository root (``from bench import tradeoffs_measure``); the scripts
themselves run by path."""
