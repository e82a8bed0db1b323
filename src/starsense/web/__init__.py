"""The local design page (``starsense design``): a thin Starlette server over the same API.

Nothing in the package imports it; ``starsense design`` loads it by name. It needs the ``web``
extra (``pip install 'starsense[web]'``).
"""
