"""SUMO itself: where its programs are (``binaries``), and the replay loop that every
exported bundle ships as ``run.py`` (``run``, standalone: it imports nothing of ours)."""
