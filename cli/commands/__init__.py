"""Command modules: each exposes `command`, a click command registered by cli/main.py."""
