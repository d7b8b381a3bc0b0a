"""Frequency-domain analysis of any diagram: margins, roots, delay intervals."""
