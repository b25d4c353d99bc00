"""MAVLink for cufund: frame conversions (:mod:`.frames`) and PX4's simulator interface (:mod:`.px4_sim`)."""
