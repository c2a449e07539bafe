"""Pictures and logs: figures, reports, TensorBoard."""
