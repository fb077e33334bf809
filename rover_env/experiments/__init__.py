"""Reproductions of the paper's experiments and validation runs."""
