"""The series elastic actuator: parameters, loop, gain design, views."""
