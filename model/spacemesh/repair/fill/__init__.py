"""Hole filling: the fills an automatic region of holes can end with, and the policy
that chooses among them (docs/REPAIR.md).
"""
