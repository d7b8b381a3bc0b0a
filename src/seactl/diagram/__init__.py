"""The one block diagram: blocks, delays, derived transfers, quasi-polynomials."""
