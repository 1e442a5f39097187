"""Figures and reports read by people: plots, the model comparison and the end-of-run summary."""
