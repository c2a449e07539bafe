"""The mentor: its policy, its demonstrations, the reward of the mentor term, diagnostics."""
