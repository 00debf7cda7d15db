"""Tests of dsim serve, the web front end."""
