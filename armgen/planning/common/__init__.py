"""Planning's shared floor: the task vocabulary and its conversion to SI that every planner
uses (:mod:`.schema`; robot + start, path + timing). No planner owns it; planners import it
and never each other (tests/test_layers.py)."""
