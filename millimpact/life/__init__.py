"""Liner life (``millimpact life``): wear and metal flow per place from a mill run, the worn profile
through time fed back to the mill (:mod:`.profile`, :mod:`.wear`, :mod:`.calibration`,
:mod:`.loop`, :mod:`.command`)."""
