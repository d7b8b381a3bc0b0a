"""Multi-joint SEA robots: the rigid-body model from a URDF and the linearized loop."""
