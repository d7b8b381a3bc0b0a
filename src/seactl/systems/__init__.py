"""The systems: the SEA, the rigid actuator and the omnidirectional base."""
