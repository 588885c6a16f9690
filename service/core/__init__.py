"""The domain: the method's stages, one package each, free of web, queue and settings code.

A module imports from its own package or from a layer below it, never from one above:
docs/architecture.md lists the layers (tests/test_boundaries.py holds the code to them).
"""
