"""``python -m cosim``: the ``cosim`` command (:func:`cosim.cli.main`)."""
import sys

from .cli import main

sys.exit(main())
