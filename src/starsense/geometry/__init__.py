"""starsense.geometry"""
