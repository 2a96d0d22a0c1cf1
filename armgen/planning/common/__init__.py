"""Planning's shared floor: the task vocabulary and its conversion to SI that every planner
uses — :mod:`.schema` (the tables), :mod:`.start` (robot + start: the start configuration on
the loaded robot, a pose start through its IK, the unit scales), :mod:`.path` (path + timing:
circle/line geometry, time law, step check, program paths) and :mod:`.symbolic` (the CasADi
pose errors of the resolved-rate steps). No planner owns it; planners import it and never each
other (tests/test_layers.py)."""
