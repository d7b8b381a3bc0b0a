"""The applications: command line, explorer, report, benchmarks."""
