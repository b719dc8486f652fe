"""The progress bar of a sweep (tqdm)."""

import sys


def progress_default() -> bool:
    if "ipykernel" in sys.modules:
        return True
    try:
        return sys.stderr.isatty()
    except (AttributeError, ValueError):
        return False


def progress_bar(enabled: bool):
    """tqdm's notebook widget where it can be shown, its text bar elsewhere."""
    from tqdm import std

    if not enabled or "ipykernel" not in sys.modules:
        return std.tqdm
    try:
        import ipywidgets  # noqa: F401  (tqdm's notebook bar needs it)
        from tqdm.notebook import tqdm as notebook_tqdm
    except ImportError:
        return std.tqdm
    return notebook_tqdm
