"""What the tests and the checks use: fault injection into long runs (:mod:`.faults`), the
engine's state hashes (:mod:`.statehash`, needs YADE) and constructed piles with known
answers (:mod:`.synthetic`)."""
