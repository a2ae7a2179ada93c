"""Jinja2 templates for the generated firmware module (shipped inside the wheel)."""
