"""`python -m paintcell …` is the `paintcell` command."""

from paintcell.cli.main import main

raise SystemExit(main())
