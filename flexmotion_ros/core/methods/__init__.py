"""The planning methods: one module per method, the table, and :func:`plan_move`."""

from .table import METHODS, Method, plan_move

__all__ = ["METHODS", "Method", "plan_move"]
