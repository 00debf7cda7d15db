"""Tests of master/recording: results, statistics, plots, nothing lost."""
