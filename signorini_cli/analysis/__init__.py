"""Rates and verdicts: what a table of errors says against the paper's proven rates."""
