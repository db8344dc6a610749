"""One module per ``depthgram`` sub-command.

Each module defines ``NAME`` (the sub-command), ``HELP`` (one line), ``add_arguments(parser)``
and ``run(args) -> int``. Modules import their heavy dependencies inside ``run`` so that
``depthgram --help`` stays fast. :mod:`depthgram.cli` finds them by listing this package.
"""
