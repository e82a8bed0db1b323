"""starsense.photometry"""
