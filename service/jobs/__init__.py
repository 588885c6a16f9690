"""Execution of long work outside the server's process: the worker functions and executors."""
