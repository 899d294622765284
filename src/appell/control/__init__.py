"""Controlled systems (method.md §4): servo constraints, dynamic conditions (2.3), motion
(2.4), reactions (2.5), control laws, relative degree and internal dynamics.
"""
