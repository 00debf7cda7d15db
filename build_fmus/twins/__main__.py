"""``python -m dsim.build_fmus.twins SCENE --out FILE.csv``: one scene's twin."""
from dsim.build_fmus.twins import main

raise SystemExit(main())
