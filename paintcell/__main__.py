"""`python -m paintcell …` is the `paintcell` command."""

from paintcell.sim.app.cli import main

raise SystemExit(main())
