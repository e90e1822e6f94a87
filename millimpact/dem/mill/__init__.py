"""``millimpact mill``: a slice of the mill in Yade and its ball-liner impact log (:mod:`.command`).
The liner's profile round the shell is :mod:`.geometry`, the contact parameters :mod:`.contact`
(or an exported law, :mod:`.law`), the slice, balls and speed :mod:`.setup`; Yade runs
``yade_scripts/mill_slice.py``, whose output :mod:`.log` reads and :mod:`.report` summarises.
"""
