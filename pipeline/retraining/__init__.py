"""Retraining as campaigns arrive: pull, reproduce, report the promotion gate; roll back."""
