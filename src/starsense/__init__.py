"""starsense: from photons to attitude, how good a star sensor can be and how good it is."""

__version__ = "0.1.0"
