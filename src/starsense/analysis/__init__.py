"""Analyses composed from the chain: limits, slew, availability, guide stars, Monte Carlo."""
