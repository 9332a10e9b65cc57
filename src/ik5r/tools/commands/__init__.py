"""One module per CLI verb; each defines ``register(subparsers)`` and a ``run(args) -> int``."""
