"""Environment control: one device API over every platform (paper §3.2)."""
