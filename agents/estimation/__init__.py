"""What the rules estimate online from the instruments: the drawn bearing (:mod:`.identification`), the
stability table of a plant (:mod:`.stability`), the posterior over the hidden damping gain (:mod:`.gain`),
the decay of the whirl mode after shocks (:mod:`.decay`) and the unbalance probe (:mod:`.unbalance`)."""
