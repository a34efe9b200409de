"""Offline GA tuning of the EFFC fuzzy force weight (DEAP), on one machine or a Dask cluster."""
