"""Derivation pipeline (method.md §1–3): validation -> kinematics -> acceleration energy
-> constraints in second-order form -> partition -> reduced equations (1.4) and reactions (1.5).

:mod:`appell.core.derive` reads like the method; each other module is one stage.
"""
