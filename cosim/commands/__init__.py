"""The subcommands of ``cosim``, one module each with ``main(args) -> exit status``.

:mod:`cosim.cli` builds the parser without them and imports the one module a command needs when
it runs (``cosim --help`` and ``cosim list`` load none of the numerics); each module imports what
it runs at its top. :mod:`cosim.commands.options` holds the option checks they share.

Owns: what each subcommand does with its parsed options. Boundaries: the options themselves are
declared in :mod:`cosim.cli`; tables are written by :mod:`cosim.report`.
"""
