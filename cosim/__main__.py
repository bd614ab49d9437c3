"""``python -m cosim``: the ``cosim`` command (:func:`cosim.cli.main`).

Owns: ``python -m cosim``. Boundaries: it holds no logic of its own.
"""
import sys

from .cli import main

sys.exit(main())
