"""Applications on top of the library: the command line, live runs, the web ground station, MAVLink and PX4,
sweeps and log replay. Nothing below imports from here."""
