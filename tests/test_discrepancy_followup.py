"""No false names: a later effect needs evidence of its own, where the effects named before it
act least; after a proposed test, a new name needs evidence from the new campaigns, and a test
meant for one effect that names another leaves it a suspect until a second test confirms it."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest

from pipeline.discrepancy.followup import (
    FollowUp,
    history_entry,
    no_longer_named,
    reduction_on,
    suspect_reason,
)
from pipeline.discrepancy.own_evidence import implausible_reason, weak_campaigns
from pipeline.discrepancy.report_text import _step_lines
from pipeline.discrepancy.search import (
    FitResult,
    SearchSettings,
    evidence_on_test,
    follow_up_gate,
    forward_search,
    qualifies_on_test,
)
from pipeline.stages.discrepancy import history_entries, history_of, write_history

OLD = [f"K{i:02d}" for i in range(1, 7)]
NEW = ["P1_01", "P1_02"]
SETTINGS = SearchSettings(n_jobs=1, n_folds=4)
THRESHOLDS = (SETTINGS.min_heldout_reduction, SETTINGS.min_heldout_t_reduction)


class LocalMisfit:
    """A fake evaluator: each missing true effect leaves ``gain`` um of held-out Z residual on
    the campaigns of ``where[effect]`` only (noise ``noise`` um elsewhere); BIC falls with the
    effects found, as a real calibration's would."""

    def __init__(self, where: dict[str, set[str]], gain: float = 5.0, noise: float = 0.5):
        self.where, self.gain, self.noise = where, gain, noise

    def __call__(self, effects, train, test, start=None):
        missing = [e for e in self.where if e not in effects]
        z = {
            c: np.full(50, self.noise + sum(self.gain for e in missing if c in self.where[e]))
            for c in test
        }
        t = {c: pd.DataFrame({"T1": np.full(50, 0.1)}) for c in test}
        bic = 100.0 * len(missing) ** 2 + 8.0 * len(effects)
        params = {f"p_{e}": (1.0, "um") for e in sorted(effects)}
        return FitResult(bic, bic, params, z, t)


def follow(targets=(), named=(), suspects=None) -> FollowUp:
    """The earlier run: it saw :data:`OLD`."""
    return FollowUp(frozenset(OLD), frozenset(named), frozenset(targets), dict(suspects or {}))


def search(where, earlier, evaluator=None):
    """The search after ``earlier`` on :data:`OLD` and :data:`NEW`, wired as the stage wires it."""
    ids = OLD + NEW
    gate = follow_up_gate(earlier, ids, SETTINGS)
    evaluator = evaluator or LocalMisfit(where)
    return forward_search(
        evaluator, ids, SETTINGS, gate=gate, on_test=evidence_on_test(earlier, ids)
    )


def diluted(effect: str) -> LocalMisfit:
    """``effect`` leaves 1 um on the new campaigns over a 3 um misfit it cannot touch anywhere:
    4 -> 3 um there (-25 %), 3.28 -> 3.00 um pooled over the eight campaigns (-9 %)."""
    return LocalMisfit({effect: set(NEW)}, gain=1.0, noise=3.0)


def test_the_effect_the_test_was_proposed_for_is_named_on_the_new_campaigns():
    result = search({"thermal_bending": set(NEW)}, follow(targets={"thermal_bending"}))
    assert result.named_effects == ["thermal_bending"] and result.suspects == {}


def test_another_effect_newly_named_by_the_test_stays_a_suspect():
    result = search({"motor_heat": set(NEW)}, follow(targets={"sensor_lag"}))
    assert result.named_effects == []
    reason = result.suspects["motor_heat"]
    assert "newly named by the new campaigns P1_01, P1_02" in reason
    assert "proposed tests for sensor_lag" in reason and "a second test must confirm" in reason
    assert result.to_dict()["suspects"] == [{"effect": "motor_heat", "reason": reason}]


def test_a_second_test_confirms_a_suspect():
    earlier = follow(targets={"sensor_lag"}, suspects={"motor_heat": "first test"})
    assert search({"motor_heat": set(NEW)}, earlier).named_effects == ["motor_heat"]


def test_a_new_name_whose_evidence_is_in_the_old_campaigns_stays_a_suspect():
    """The misfit sits where the earlier run had looked; the new campaigns show none of it."""
    result = search({"motor_heat": {"K01", "K02"}}, follow(targets={"motor_heat"}))
    assert result.named_effects == []
    assert "its evidence is not in the new campaigns" in result.suspects["motor_heat"]


def test_without_an_earlier_run_or_with_a_name_it_kept_nothing_is_gated():
    assert search({"motor_heat": set(NEW)}, None).named_effects == ["motor_heat"]
    kept = follow(named={"motor_heat"})
    assert search({"motor_heat": {"K01"}}, kept).named_effects == ["motor_heat"]


def test_with_no_new_campaign_the_earlier_suspects_stay_suspects():
    earlier = follow(suspects={"motor_heat": "named by a test for sensor_lag"})
    reason = suspect_reason("motor_heat", earlier, OLD, 0.9, 0.9, THRESHOLDS)
    assert reason == "named by a test for sensor_lag"
    assert suspect_reason("ambient_variation", earlier, OLD, 0.9, 0.9, THRESHOLDS) is None


def test_a_readings_only_effect_needs_its_temperature_evidence_on_the_new_campaigns():
    earlier = follow(targets={"sensor_lag"})
    ids = OLD + NEW
    assert suspect_reason("sensor_lag", earlier, ids, 0.9, 0.05, THRESHOLDS, True) is not None
    assert suspect_reason("sensor_lag", earlier, ids, 0.0, 0.5, THRESHOLDS, True) is None


def test_the_target_of_a_test_may_pass_on_the_tests_campaigns_alone():
    """The earlier campaigns could not show it: pooled, their misfit dilutes the test's fall."""
    result = search({}, follow(targets={"thermal_bending"}), diluted("thermal_bending"))
    assert result.named_effects == ["thermal_bending"]
    step = result.steps[0].to_dict()
    assert step["evidence"]["heldout_reduction"] == pytest.approx(1 - 3 / np.sqrt(86 / 8), abs=1e-5)
    assert step["evidence"]["heldout_reduction_on_test"] == pytest.approx(0.25, abs=1e-5)
    assert step["evidence"]["passes_on_test"] is True
    lines = "\n".join(_step_lines(step, {}, SETTINGS.min_heldout_reduction))
    assert "named on the campaigns of the test proposed for it" in lines
    assert "held-out Z residual changed by -25 %" in lines
    assert "named on the temperatures alone" not in lines


def test_only_the_target_of_the_test_may_pass_on_its_campaigns():
    """The same diluted evidence names neither another effect nor the target without a test."""
    assert search({}, follow(targets={"sensor_lag"}), diluted("motor_heat")).named_effects == []
    assert search({}, None, diluted("thermal_bending")).named_effects == []
    candidates = search({}, None, diluted("thermal_bending")).to_dict()["candidates_by_step"]
    assert "passes_on_test" not in candidates[0]["candidates"][0]


def test_on_the_tests_campaigns_a_route_counts_only_when_the_pooled_rms_does_not_rise():
    assert qualifies_on_test("thermal_bending", (0.3, 0.0), (0.0, -0.5), SETTINGS)
    assert not qualifies_on_test("thermal_bending", (0.3, 0.0), (-0.01, 0.0), SETTINGS)
    assert not qualifies_on_test("thermal_bending", (0.1, 0.1), (0.05, 0.05), SETTINGS)
    # an effect of the readings only passes through its temperatures, never through Z
    assert not qualifies_on_test("sensor_lag", (0.9, 0.0), (0.1, 0.0), SETTINGS)
    assert qualifies_on_test("sensor_lag", (-0.5, 0.3), (-0.2, 0.01), SETTINGS)
    assert evidence_on_test(follow(targets={"sensor_lag"}), OLD) is None  # no new campaign


def test_the_reduction_is_pooled_over_the_named_campaigns_only():
    before = {"A": np.full(4, 2.0), "B": np.full(4, 10.0)}
    after = {"A": np.full(4, 1.0), "B": np.full(4, 10.0)}
    assert reduction_on(["A"], before, after) == pytest.approx(0.5)
    assert reduction_on(["A", "B"], before, after) < 0.05
    assert np.isnan(reduction_on(["C"], before, after))


def test_the_stage_keeps_the_history_a_tested_run_needs_and_forgets_it_when_untestable(tmp_path):
    doc = {
        "status": "tested",
        "campaigns": OLD,
        "named_effects": ["ambient_variation"],
        "suspects": [{"effect": "motor_heat", "reason": "why"}],
        "identifiability": {
            "sensor_lag": {"class": "not_identifiable"},
            "ambient_variation": {"class": "named"},
        },
    }
    path = tmp_path / "history.json"
    untestable = history_of({"status": "untestable", "named_effects": []})
    write_history(path, {"vmc": history_of(doc), "lathe": untestable})
    entries = json.loads(path.read_text())["machines"]
    assert entries == {"vmc": history_entry(doc), "lathe": {"status": "untestable"}}
    back = {m: FollowUp.from_document(entry) for m, entry in history_entries(path).items()}
    assert back == {  # each machine's own; the untestable one starts afresh
        "vmc": FollowUp(
            frozenset(OLD),
            frozenset({"ambient_variation"}),
            frozenset({"sensor_lag"}),
            {"motor_heat": "why"},
        ),
        "lathe": None,
    }


def test_the_report_lists_the_suspects_with_their_reason():
    from pipeline.discrepancy.report_text import _suspect_lines

    lines = _suspect_lines([{"effect": "motor_heat", "reason": "newly named by P1_01"}])
    assert "**Suspects**" in lines[1] and "- `motor_heat`: newly named by P1_01." in lines
    assert _suspect_lines([]) == []


def test_an_effect_named_before_that_no_longer_passes_is_reported_no_longer_named():
    from pipeline.discrepancy.report_text import _no_longer_named_lines

    earlier = follow(targets=("thermal_bending",), named=("motor_heat",))
    result = search({"thermal_bending": set(NEW)}, earlier)
    assert result.named_effects == ["thermal_bending"]  # motor_heat is tried again and fails
    last = {
        c.effect: (c.heldout_reduction, c.heldout_t_reduction) for r in result.rounds for c in r
    }
    dropped = no_longer_named(earlier, result.named_effects, result.suspects, last)
    assert [d["effect"] for d in dropped] == ["motor_heat"]
    assert "no longer passes the search's rule (held-out Z -0 %" in dropped[0]["reason"]
    held = no_longer_named(earlier, [], {"motor_heat": "its steps are not measured"}, last)
    assert "held back: its steps are not measured" in held[0]["reason"]
    assert no_longer_named(None, [], {}, last) == []
    assert no_longer_named(earlier, ["motor_heat"], {}, last) == []
    lines = _no_longer_named_lines(dropped)
    assert "**No longer named**" in lines[1] and lines[-1].startswith("- `motor_heat`: with the")


class Remainder:
    """A fake evaluator whose second candidate only mops up what the first leaves.

    ``nonlinear_bearing_heat`` (hidden) leaves 5 um on K01-K04 and 1 um on K05-K08; once it is
    named, its imperfect form leaves ``remainder`` um on K01-K04, which ``thermal_bending``
    (not hidden) fits; ``centrifugal_growth``, when ``second`` is True, is hidden too and
    leaves 2 um on every campaign.
    """

    def __init__(self, remainder: float = 1.5, second: bool = False):
        self.remainder, self.second = remainder, second

    def __call__(self, effects, train, test, start=None):
        def level(campaign: str) -> float:
            strong = campaign in {"K01", "K02", "K03", "K04"}
            value = 0.5
            if "nonlinear_bearing_heat" not in effects:
                value += 5.0 if strong else 1.0
            elif strong and "thermal_bending" not in effects:
                value += self.remainder
            if self.second and "centrifugal_growth" not in effects:
                value += 2.0
            return value

        z = {c: np.full(50, level(c)) for c in test}
        t = {c: pd.DataFrame({"T1": np.full(50, 0.1)}) for c in test}
        bic = 100.0 * float(np.mean([level(c) ** 2 for c in train])) + 8.0 * len(effects)
        params = {f"p_{e}": (1.0, "um") for e in sorted(effects)}
        return FitResult(bic, bic, params, z, t)


IDS = [f"K{i:02d}" for i in range(1, 9)]


def test_a_second_effect_that_fits_what_the_first_leaves_is_a_suspect():
    result = forward_search(Remainder(), IDS, SETTINGS)
    assert result.named_effects == ["nonlinear_bearing_heat"]
    reason = result.suspects["thermal_bending"]
    assert "where nonlinear_bearing_heat already act" in reason
    assert "(K05, K06, K07, K08)" in reason


def test_a_second_effect_with_evidence_of_its_own_is_named():
    result = forward_search(Remainder(remainder=0.0, second=True), IDS, SETTINGS)
    assert result.named_effects == ["nonlinear_bearing_heat", "centrifugal_growth"]
    assert result.suspects == {}


def test_the_weak_campaigns_are_where_the_named_effects_lowered_the_residual_least():
    evaluator = Remainder()
    base = evaluator(frozenset(), IDS, IDS)
    named = evaluator(frozenset({"nonlinear_bearing_heat"}), IDS, IDS)
    weak = weak_campaigns(
        (base.z_residual_um, base.t_residual_k), (named.z_residual_um, named.t_residual_k)
    )
    assert weak == ["K05", "K06", "K07", "K08"]


class CalibratedAs(LocalMisfit):
    """``effect`` fits a misfit on every campaign; its calibration gives ``values`` (name ->
    (value, unit)) and the baseline's always gives ``baseline``."""

    def __init__(self, effect: str, values: dict, baseline: dict | None = None):
        super().__init__({effect: set(IDS)})
        self.effect, self.values, self.baseline = effect, values, dict(baseline or {})

    def __call__(self, effects, train, test, start=None):
        fit = super().__call__(effects, train, test, start)
        fit.params.update(self.baseline)
        if self.effect in effects:
            fit.params.update(self.values)
        return fit


def flatter_law(exponent: float) -> CalibratedAs:
    """``nonlinear_bearing_heat`` calibrated with the exponent ``exponent``."""
    return CalibratedAs("nonlinear_bearing_heat", {"bearing_exponent": (exponent, "1")})


def test_an_effect_whose_calibration_is_not_its_physics_is_a_suspect():
    """A bearing law flatter than linear is the cooling or a drive loss, not bearing friction."""
    flat = forward_search(flatter_law(0.87), IDS, SETTINGS)
    assert flat.named_effects == []
    assert "bearing_exponent = 0.87 lies outside 1.15-3" in flat.suspects["nonlinear_bearing_heat"]
    steep = forward_search(flatter_law(1.6), IDS, SETTINGS)
    assert steep.named_effects == ["nonlinear_bearing_heat"]
    assert implausible_reason("motor_heat", {"q_motor_W_per_krpm": (50.0, "W/krpm")}) is None


def front_heavy_column(bending: float) -> CalibratedAs:
    """``thermal_bending`` calibrated at ``bending`` um/K beside a column coefficient of 7 um/K."""
    return CalibratedAs(
        "thermal_bending",
        {"bending_um_per_K": (bending, "um/K")},
        {"alpha_column_um_per_K": (7.0, "um/K")},
    )


def test_a_front_rear_law_a_lopsided_column_expansion_gives_is_not_bending():
    """Up to half the column's coefficient, unequal weights of its faces explain the law."""
    result = forward_search(front_heavy_column(2.1), IDS, SETTINGS)
    assert result.named_effects == []
    reason = result.suspects["thermal_bending"]
    assert "is not above 0.5 x alpha_column_um_per_K = 3.5" in reason


def test_a_front_rear_law_of_the_other_sign_is_not_bending():
    result = forward_search(front_heavy_column(-5.0), IDS, SETTINGS)
    assert result.named_effects == []
    assert "bending_um_per_K = -5 lies outside 0-50" in result.suspects["thermal_bending"]


def test_a_front_rear_law_beyond_any_weighting_of_the_faces_is_bending():
    assert forward_search(front_heavy_column(6.0), IDS, SETTINGS).named_effects == [
        "thermal_bending"
    ]


def _trial_doc(campaigns, named, suspects=()):
    """A rerun's ``discrepancy.json``: bending not identifiable with a visible heater test."""
    proposed = {
        "visible": True,
        "name": "heater",
        "expected_signal_sigma": 3.0,
        "campaigns": 1,
        "spindle_program": [{"from_min": 0, "rpm": 0}],
        "sample_interval_s": 180,
        "duration_h": 4,
    }
    cls = "named" if "thermal_bending" in named else "not_identifiable"
    return {
        "campaigns": list(campaigns),
        "named_effects": list(named),
        "suspects": [{"effect": e, "reason": "why"} for e in suspects],
        "identifiability": {"thermal_bending": {"class": cls, "proposed_test": proposed}},
        "rmse_um_before": 2.0,
        "rmse_um_after": 1.0,
        "rmse_T_K_before": 0.2,
        "rmse_T_K_after": 0.1,
    }


def test_a_trial_follow_up_reruns_with_the_earlier_run_until_the_effect_is_named(
    tmp_path, monkeypatch
):
    """Round after round, each rerun gets the run before it (as the stage keeps it); the
    follow-up records the rounds, what was named and the suspects of the last rerun."""
    import benchmarks.discrepancy_trials as trials

    first = _trial_doc(OLD, [])
    reruns = iter(
        [
            _trial_doc([*OLD, "P1_01"], [], suspects=["motor_heat"]),
            _trial_doc([*OLD, "P1_01", "P2_01"], ["thermal_bending"], suspects=["motor_heat"]),
        ]
    )
    earlier = []

    def workflow(folder, report, section, params_file=None, follow=None):
        earlier.append(follow)
        return next(reruns)

    def write_plan(folder, proposed, effects, seed, n, round_):
        return [f"P{round_}_01"]

    monkeypatch.setattr(trials, "run_workflow", workflow)
    monkeypatch.setitem(trials.GENERATORS, "fake", trials.Generator("fake", None, write_plan))
    (tmp_path / "raw").mkdir()
    (follow,) = trials.follow_plan(
        tmp_path / "raw", first, ["thermal_bending"], ["thermal_bending"], 1, None, tmp_path, "fake"
    )
    assert follow.effect_named and follow.rounds == 2 and follow.suspects == ("motor_heat",)
    assert [f.campaigns for f in earlier] == [frozenset(OLD), frozenset([*OLD, "P1_01"])]
    assert earlier[1].suspects == {"motor_heat": "why"}


def test_a_later_effect_whose_own_signature_shows_needs_no_evidence_where_the_first_acts():
    def bending_signature(effect, current, augmented):
        return "its own structure" if effect == "thermal_bending" else None

    result = forward_search(Remainder(), IDS, SETTINGS, signature=bending_signature)
    assert result.named_effects == ["nonlinear_bearing_heat", "thermal_bending"]
    assert result.suspects == {}
