"""The slow, obvious truth: exact option models and exact planning."""
