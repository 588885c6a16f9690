"""The ego in SUMO: who drives it (``controllers``: SUMO's drivers, plug-ins,
certificates), and the replay of a test-case with one of them, judged by the checker
(``replay``; ``replay_child`` is the child process's side), and the same replay as a
Gymnasium environment driven step by step from outside (``gym_env``)."""
