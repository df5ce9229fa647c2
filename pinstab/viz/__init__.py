"""Seeing a simulation: meshcat recordings (standalone HTML, live) and matplotlib charts."""
