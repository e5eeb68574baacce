"""Control: the backstepping law and its disturbance adaptation (compiled and matrix forms), fuzzy rate schedules."""
