"""User loop files: validated and compiled onto the block diagram."""
