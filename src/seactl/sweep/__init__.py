"""Chunked, resumable design-space sweeps on processes or Dask."""
