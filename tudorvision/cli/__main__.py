"""``python -m tudorvision.cli``: the ``tudorvision`` command."""
import sys

from . import main

sys.exit(main())
