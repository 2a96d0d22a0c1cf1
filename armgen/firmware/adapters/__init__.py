"""One adapter per planner → the controller's task (:class:`~..configuration.FirmwareTask`),
each filling the firmware templates of its controller mode. The resolved-rate adapters
(cartesian, fault_tolerant, wgpm) take the planner's typed configuration the plan was made with
(its step after any refinement, a program's final motion); the playback adapters (ptp, snake)
take it with the plan, whose coefficients or samples they play. :mod:`..tasks` picks the adapter."""
