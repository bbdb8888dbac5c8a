"""Running independent tasks on this machine's processes or a Ray cluster (:mod:`.executors`)."""
