"""Options: the bundle of tensors, its builders, and options discovered from demonstrations."""
