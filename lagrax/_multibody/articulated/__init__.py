"""Articulated bodies on a fixed base: planar and spatial chains, trees, and the
equations the recursions evaluate for them."""
