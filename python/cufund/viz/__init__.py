"""Visualisation: plots, MeshCat replays and live viewing. Imported only where used, never by the simulator."""
