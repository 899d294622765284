"""Simulation: consistent initial values, integration with drift control and events,
solutions with export and plots, parameter sweeps on Dask.
"""
