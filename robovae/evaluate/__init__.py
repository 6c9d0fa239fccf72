"""Evaluate: RA / FRE metrics, sample and population statistics, rendering, experiments."""
