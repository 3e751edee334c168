"""Plots (matplotlib, Agg backend): one module per figure."""
