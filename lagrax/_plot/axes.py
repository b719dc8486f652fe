"""The axes a figure of `lagrax.plot` draws on."""


def axes_for(ax):
    """`ax`, or the axes of a new figure when it is `None` (matplotlib imported only
    when a figure is drawn)."""
    if ax is None:
        import matplotlib.pyplot as plt

        _, ax = plt.subplots()
    return ax
