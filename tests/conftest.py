"""Test-suite configuration: hypothesis profiles.

The property tests (``hypothesis``) draw their examples from a fixed seed by
default (profile ``"repeatable"``: ``derandomize=True``, no example database),
so ``make test`` and CI see the same examples on every run and a red run is
a change in the code, not a new draw. To search for new counterexamples, run
with another profile::

    HYPOTHESIS_PROFILE=explore .venv/bin/python -m pytest tests/test_files_fuzz.py

(``explore``: random draws; 500 examples where a test does not set its own ``max_examples``.)
"""
from __future__ import annotations

import os

from hypothesis import settings

settings.register_profile("repeatable", derandomize=True, database=None)
settings.register_profile("explore", derandomize=False, max_examples=500)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "repeatable"))
