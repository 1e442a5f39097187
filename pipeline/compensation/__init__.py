"""From the champion to the machine: the compensation runtime, controller exports, replay proof.

- its settings, the ``compensation:`` section of ``params.yaml``, are
  :mod:`pipeline.settings.compensation`;
- :mod:`~pipeline.compensation.bundle`: what the runtime loads per axis (the champion, its
  fallbacks, the ranges seen in training);
- :mod:`~pipeline.compensation.guard`: each cycle's input checks;
- :mod:`~pipeline.compensation.axis`: one axis' offset per cycle (fallbacks, hold, decay, limits);
- :mod:`~pipeline.compensation.runtime`: the cycle loop between a source and a sink;
- :mod:`~pipeline.compensation.files` and :mod:`~pipeline.compensation.opcua`: sources and sinks;
- :mod:`~pipeline.compensation.replay`: the proof on held-out campaigns;
- :mod:`~pipeline.compensation.exports`: what controllers take (coefficients, TEMPCOMP,
  SINUMERIK);
- :mod:`~pipeline.compensation.sensor_budget`: the best model with k sensors, fallbacks' scores.
"""
