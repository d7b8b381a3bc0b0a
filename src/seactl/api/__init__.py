"""The public API: seactl.System and its kinds, results, public functions."""
