"""``python -m dsim.build_fmus``: same as ``dsim build-fmus``."""
import sys

from dsim.build_fmus.build import main

sys.exit(main())
