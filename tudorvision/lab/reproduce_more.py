"""Sections of ``tudorvision reproduce`` for chapter 8 (damping) and section 9.3 (catching).

They call the experiments of :mod:`tudorvision.lab.ch8_experiments`,
:mod:`tudorvision.lab.ch8_extra` and :mod:`tudorvision.lab.catch` and turn their
numbers into rows beside the seed's.
"""
from __future__ import annotations

__all__ = ["MORE_SECTIONS"]

#: Sections added to :data:`tudorvision.lab.reproduce_sections.SECTIONS`.
MORE_SECTIONS = ()
