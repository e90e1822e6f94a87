"""Run methods: :mod:`.registry` is the one table of ``--method`` names; each method family is a
module (:mod:`.full`, :mod:`.reduced`, :mod:`.hertz_modal`, :mod:`.hertz`) with a runner
``run(scene, plan, options, progress) -> RunOutput``; :mod:`.run` computes and writes one run;
:mod:`.static` is the static contact solve. Imports results and below.
"""
