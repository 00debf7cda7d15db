"""Tools built on the API: the command line, sweeps, regression runs, validation and
comparison."""
