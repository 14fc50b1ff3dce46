"""``python -m gfb_env ...`` is the ``gfb`` command."""

from gfb_env.cli import main

raise SystemExit(main())
