"""Reductions (method.md §5): first integrals as constraints, cyclic coordinates and
Routh reduction.
"""
