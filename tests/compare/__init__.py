"""Tests of yadecd: see tests/README.md."""
