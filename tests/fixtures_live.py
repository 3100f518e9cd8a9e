"""Live server fixtures (daphne in a subprocess on a real socket)."""
