"""Build dsim's FMUs (pythonfmu) into build/fmus and pack ssp/ scenes into build/ssp."""
