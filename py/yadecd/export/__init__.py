"""Exporting Contact Dynamics problems to other solvers: FCLIB files and Siconos solves
(:mod:`.fclib`)."""
