"""Helpers below the simulator that import nothing else of gvsjax: typed key=value
configuration (``keyvalue``), shared figure style (``plots``), device sharding
(``sharding``), multi-process start-up (``distributed``) and the training log (``runlog``)."""
