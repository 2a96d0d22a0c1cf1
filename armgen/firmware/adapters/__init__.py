"""One adapter per planner: its plan (and, for the resolved-rate planners, the planner's typed
configuration the plan was made with) → the controller's task (:class:`~..configuration.FirmwareTask`).
Each module fills the firmware templates of its controller mode; :mod:`..tasks` picks the adapter."""
