"""Run methods: :mod:`.registry` is the one table of ``--method`` names; each method family is a
module (:mod:`.full`, :mod:`.reduced`, :mod:`.hertz_modal`, :mod:`.hertz`) with a runner
``run(scene, plan, options, progress) -> RunOutput``; :mod:`.free_phase` is the reduced methods'
time loop (integrator in contact, closed-form free vibration between); :mod:`.run` computes and
writes one run; :mod:`.static` is the static contact solve. The runners are where the scene stops:
they hand the stages below the mesh and the plan's numbers. Imports results and below.
"""
