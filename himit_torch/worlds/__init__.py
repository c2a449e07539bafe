"""Worlds: the multirooms gridworld, tables of any tabular world, Gymnasium."""
