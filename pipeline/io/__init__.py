"""Raw campaign folders (``docs/data-contract.md``) read into tidy tables.

Campaign metadata (``campaign.yaml``), temperature and displacement logs and laser runs are read
as they are, aligned on one time base, and every problem that stops a file from being read is
collected with its campaign, file, line and column for the validation report.
"""
