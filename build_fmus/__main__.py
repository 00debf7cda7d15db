"""``python -m build_fmus``: same as ``dsim build-fmus``."""
import sys

from build_fmus.build import main

sys.exit(main())
