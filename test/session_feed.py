"""Feed a simulated sensor stream to a session as the node's image queue does (test helper)."""

from __future__ import annotations


def feed(session, config, samples) -> list:
    """Give ``samples`` (:func:`rwhec_ros.simulation.simulated_stream`: ``(stamp, camera or
    None, data)``) to ``session``: each pose as it comes, each image once a pose brackets it
    (its outcome is then ``add_image``'s answer). Returns the images' outcomes, in order."""
    outcomes, waiting = [], []
    for stamp, cam, data in samples:
        if cam is not None:
            waiting.append((cam, stamp, data))
            continue
        session.add_pose(stamp, data, source=config.pose_source.parent)
        while waiting and session.pose_ready(waiting[0][1]):
            outcomes.append(session.add_image(*waiting.pop(0)))
    assert not waiting
    return outcomes
