"""Foundations: errors' fields, validation, design axes, limits, outputs, threads."""
