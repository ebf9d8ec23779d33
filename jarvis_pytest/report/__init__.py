"""Reporting: the paper's TSR/SSR tables rolled up from per-task results."""
