"""Building blocks of the ``validate`` stage (:mod:`pipeline.stages.validate` runs them).

- :mod:`~pipeline.validation.problems`: the report entry :class:`Problem`, the stage outcome
  :class:`ValidationResult`, :class:`NoValidCampaignError` and the raw file names problems name;
- :mod:`~pipeline.validation.limits`: the check limits from ``params.yaml`` ``validate:``;
- :mod:`~pipeline.validation.texts`: message and action of every check id;
- :mod:`~pipeline.validation.findings`: Pandera ``SchemaErrors`` -> located findings;
- :mod:`~pipeline.validation.rendering`: findings -> grouped, worded problems;
- :mod:`~pipeline.validation.campaign_checks`, :mod:`~pipeline.validation.sample_checks`,
  :mod:`~pipeline.validation.laser_checks`: validation of campaign.yaml, temperature.csv /
  displacement.csv and laser.csv;
- :mod:`~pipeline.validation.ingest_problems`: the problems ``ingest`` already found;
- :mod:`~pipeline.validation.tables`: one campaign's rows, the valid campaigns' outputs;
- :mod:`~pipeline.validation.report`: ``reports/validation.json``, the no-valid-campaign error
  and the quarantine log line.

All functions are pure (no I/O, inputs never modified).
"""
