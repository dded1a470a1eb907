"""The controller: position-based impedance control (eqs. 2-6, :mod:`.impedance`)
and the force-tracking laws that choose its reference (:mod:`.laws`)."""
