"""Geometric / thermal error separation and the model inputs.

The spindle thermal error (displacement minus its value at the run's reference), runs of
campaigns cut from one record, temperature rises and speed responses (shared by training and
serving), and the patent's polynomial separation of linear-axis positioning error.
"""
