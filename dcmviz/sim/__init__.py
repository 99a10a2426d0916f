"""Backends that realise the walker's commands: a point mass (`lip`) and MuJoCo humanoids."""
