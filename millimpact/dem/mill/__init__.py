"""``millimpact mill``: a slice of the mill in Yade and its ball-liner impact log (:mod:`.command`).
The liner's profile round the shell is :mod:`.geometry`, the contact parameters :mod:`.contact`
(or an exported law, :mod:`.law`), the slice, balls and speed :mod:`.setup`; one run (:mod:`.run`)
runs ``yade_scripts/mill_slice.py`` in Yade, whose output :mod:`.log` reads, :mod:`.report` and
:mod:`.abrasion` summarise; a SAG charge's rock is :mod:`.charge`.
"""
