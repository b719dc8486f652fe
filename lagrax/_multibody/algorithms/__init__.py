"""Featherstone's recursions (ABA, CRBA, RNEA) on fixed and free roots, their
analytic derivatives, and the spatial algebra they run on."""
