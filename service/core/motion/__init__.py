"""How cars move: Step 1's drives in libsumo (``poses``), the lane events of a drive,
collisions between drives, queues on a fork, kinematic bounds on timing, the invariants every
returned trajectory keeps, and ego trajectories read from files."""
