"""starsense.analysis"""
