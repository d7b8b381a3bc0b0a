"""The rigid actuator: parameters, loop and gain design."""
