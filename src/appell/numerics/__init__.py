"""Numerics: compiled blocks and the split solve at a state (NumPy and C backends), the
independent augmented-system cross-check, and the Dynamics contract with the simulator.
"""
