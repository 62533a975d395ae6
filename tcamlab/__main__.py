"""``python -m tcamlab``: the same as the ``tcamlab`` console script."""

from tcamlab.cli import main

main()
