"""TrajectoryFollower's block look-ahead publishes what sampling the trajectory at each tick gives."""

import numpy as np

from cufund.core.components import Bus
from cufund.core.messages import Topics
from cufund.planning import MinimumSnapTrajectory, TrajectoryFollower


def test_block_lookahead_equals_direct_sampling_on_and_off_the_grid():
    traj = MinimumSnapTrajectory(np.array([[0, 0, 1.0], [1, 0, 1.5], [1, 1, 1.0], [0, 1, 1.2]]), v_max=1.0, a_max=2.0)
    follower = TrajectoryFollower(traj, rate_hz=250.0, block=64)  # small blocks: several refills
    bus = Bus()
    times = [0.3 + k / 250.0 for k in range(400)] + [1.23456789]  # the last one is off the grid
    for t in times:
        follower.update(t, None, bus)  # type: ignore[arg-type]
        msg = bus.get(Topics.TRAJECTORY_SETPOINT)
        ref = traj.sample(np.array([t]))
        assert msg.t == t
        np.testing.assert_allclose(msg.p_W, ref.p_W[0], rtol=0, atol=1e-12)
        np.testing.assert_allclose(msg.a_W, ref.a_W[0], rtol=0, atol=1e-9)
        assert abs(msg.yaw_rate - ref.yaw_rate[0]) < 1e-12
