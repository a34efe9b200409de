"""Built-in fuzzy systems as ``hybridnav-fis/1`` JSON files (``NAME.json`` is built-in ``NAME``)."""

__all__: list[str] = []   # data files only
