"""Tests of master/tools: the command line, its errors, files, the wheel."""
