"""starsense.catalog"""
