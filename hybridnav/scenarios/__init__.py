"""Built-in scenarios, stored as TOML data files (see :func:`hybridnav.world.load_scenario`).

``NAME.toml`` here is the built-in scenario ``NAME``; ``data/`` holds grid maps referenced as
``map = "movingai:NAME"`` (``data/NAME.map``, with its MovingAI ``NAME.map.scen`` queries).
The layouts reconstruct the papers' figures: the papers give starts and goals, but obstacle
coordinates only in figures, so obstacle positions are approximations.
"""

__all__: list[str] = []   # data files only
