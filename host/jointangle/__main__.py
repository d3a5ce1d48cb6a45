"""Allow `python -m jointangle`."""

from jointangle.cli.main import main

raise SystemExit(main())
