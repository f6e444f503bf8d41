"""Weak forms, one small module per model (only pure functions of the fields here)."""
