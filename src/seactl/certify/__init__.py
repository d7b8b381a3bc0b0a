"""Compiled kernels and the proofs that make the scans' verdicts certain."""
