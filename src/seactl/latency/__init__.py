"""Latency: maps, jitter margins, loop placement, Monte Carlo timing."""
