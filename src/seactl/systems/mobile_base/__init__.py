"""The omnidirectional mobile base."""
