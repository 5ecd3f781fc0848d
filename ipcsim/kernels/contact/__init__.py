"""Contact: distances, the barrier and its mollifier, plane and pair barriers, the
penalty baseline, friction, the broad phase, CCD and exact intersection predicates."""
