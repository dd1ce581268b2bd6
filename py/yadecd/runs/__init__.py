"""Managing long runs: verified checkpoints (:mod:`.checkpoint`), the physical state of a scene
saved and restored (:mod:`.runstate`, needs YADE), carrying a run between machines
(:mod:`.carry`), what its wall time went into (:mod:`.cost`) and the ensemble driver
(:mod:`.ensemble`). All but :mod:`.runstate` import without YADE."""
