"""The sampled controller as code (C99, Python, JSON) and as OS processes."""
