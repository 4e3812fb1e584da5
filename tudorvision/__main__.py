"""``python -m tudorvision``: the ``tudorvision`` command (same as ``python -m tudorvision.cli``)."""
import sys

from .cli import main

sys.exit(main())
