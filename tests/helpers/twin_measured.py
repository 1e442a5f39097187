"""A twin-generated spindle campaign as the discrepancy workflow reads a measured one."""

from __future__ import annotations

from pipeline.discrepancy.data import MeasuredCampaign


def measured_from_twin(campaign, drop: tuple[str, ...] = ()) -> MeasuredCampaign:
    """Return ``campaign`` (a :class:`pipeline.twin.campaigns.SpindleCampaign`) as measured.

    Z is referenced at its first sample; sensors in ``drop`` are left out.
    """
    t = campaign.temperature["elapsed_s"].to_numpy()
    temps = campaign.temperature.drop(columns=["elapsed_s", *drop])
    z = campaign.displacement["Z"].to_numpy()
    return MeasuredCampaign(
        campaign_id=campaign.info.campaign_id,
        t_s=t,
        rpm=campaign.program.value_at(t),
        temperatures=temps,
        roles={s.name: s.role for s in campaign.sensors if s.name in temps.columns},
        z_um=z - z[0],
        program=campaign.program,
        heat_loads=campaign.heat_loads,
    )
