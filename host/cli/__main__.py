"""``python -m lost.host.cli``: the ``lost`` command."""

from . import main

raise SystemExit(main())
