"""starsense.sensor"""
