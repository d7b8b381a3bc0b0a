"""Time responses: continuous (exact delays) and sampled, and their verdicts."""
