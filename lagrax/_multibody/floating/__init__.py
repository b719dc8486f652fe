"""A tree of joints on a free-floating base: its system and its derivatives."""
