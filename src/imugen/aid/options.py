"""Options of ``imugen aid`` (:class:`AidOptions`); imports nothing of the stage."""

from __future__ import annotations

from dataclasses import dataclass, field

from imugen.core.options import DRAWS, Command, argument, floats, option


def _xyz(text: str) -> tuple[float, float, float]:
    return floats(text, 3, "X,Y,Z in metres")


@dataclass(frozen=True, kw_only=True)
class AidOptions:
    """Receiver, scenarios, companion sensors and filter settings of the aid stage (config
    blocks ``gnss``, ``scenarios``, ``aided``, ``companions``; see config/README.md).

    Scenarios come as the command line's specs (``scenario``) or, in Python, as the config's
    three keys (``intervals``: declared ``{kind, start_s, duration_s, <parameters>}``,
    ``draw_kinds``: kinds drawn per sequence, ``outage_durations_s``: the durations a drawn
    outage takes), not both. ``nhc=None`` turns the non-holonomic constraint on for a ``car``
    truth; ``nhc_slip_sd_mps=None`` takes the vehicle's slip from the truth's plausibility
    report (:func:`imugen.aid.stage.truth_slip_sd`); ``seed=None`` the shard's simulation seed.
    Checked when made (one-line errors naming the option).
    """

    receiver: str = option(
        "standalone", help="receiver preset: phone, standalone, sbas or rtk", config="gnss.receiver"
    )
    rate_hz: float | None = option(
        None, flag="--gnss-rate-hz", unit="Hz", shown="the receiver's", config="gnss.rate_hz",
        help="GNSS epoch rate",
    )  # fmt: skip
    draw: str = option(
        "ranges", flag="--gnss-draw", choices=DRAWS, config="gnss.draw",
        help="receiver error levels drawn in the preset's ranges per sequence, or nominal",
    )  # fmt: skip
    lever_arm_b_m: tuple = option(
        (0.0, 0.0, 0.0), flag="--lever-arm", metavar="X,Y,Z", unit="m", parse=_xyz,
        config="gnss.lever_arm_b_m", help="antenna lever arm, body frame",
    )  # fmt: skip
    lever_arm_sd_m: float = option(
        0.0, flag="--lever-arm-sd", unit="m", config="gnss.lever_arm_sd_m",
        help="per-axis spread of the lever arm drawn per sequence",
    )  # fmt: skip
    scenario: tuple[str, ...] = option(
        (), many="append", metavar="SPEC",
        help="KIND:DURATION@START[,param=value] declared; outage:DURATION drawn per sequence; "
        "KIND drawn with the documented distributions (repeatable)",
    )  # fmt: skip
    intervals: tuple = option(
        (), cli=False, help="declared intervals", config="scenarios.intervals"
    )
    draw_kinds: tuple = option(
        (), cli=False, help="kinds drawn per sequence", config="scenarios.draw"
    )
    outage_durations_s: tuple = option(
        (30.0, 60.0, 120.0, 180.0), cli=False, unit="s", config="scenarios.outages_s",
        help="durations a drawn outage takes (imugen.aid.scenarios.OUTAGE_PRESETS_S)",
    )  # fmt: skip
    settle_s: float = option(
        60.0, unit="s", config="scenarios.settle_s", help="earliest start of a drawn interval"
    )
    tuning_level: str = option(
        "law", choices=("nominal", "upper", "law"), config="aided.tuning_level",
        help="filter noise from the grade's (and receiver's) nominal values, the top of their "
        "ranges, or the law they are drawn from (consistent over the population)",
    )  # fmt: skip
    gnss_bias_states: bool = option(
        True, flag="--no-gnss-bias-states", config="aided.gnss_bias_states",
        help="no receiver-bias states",
    )  # fmt: skip
    scale_factors: bool = option(False, config="aided.scale_factors", help="estimate scale factors")
    gyro_cross_coupling: bool = option(
        True, flag="--no-cross-coupling", config="aided.cross_coupling",
        help="do not estimate the gyro and accelerometer cross-coupling",
    )  # fmt: skip
    nhc: bool | None = option(
        None, config="aided.nhc", shown="on for a car truth", help="non-holonomic constraint"
    )
    nhc_slip_sd_mps: tuple | None = option(
        None, flag="--nhc-slip-sd", metavar="LAT[,VERT]", unit="m/s",
        parse=floats, config="aided.nhc_slip_sd_mps",
        shown="the truth's plausibility report", help="vehicle slip NHC must cover, 1-sigma",
    )  # fmt: skip
    zupt: bool = option(
        True, flag="--no-zupt", config="aided.zupt", help="no zero-velocity updates"
    )
    gate_sigma: float = option(
        0.0, config="aided.gate_sigma", help="innovation gate in sigmas (0: off)"
    )
    align_speed_mps: float = option(
        5.0, flag="--align-speed", unit="m/s", config="aided.align_speed_mps",
        help="GNSS speed of a moving alignment",
    )  # fmt: skip
    eval_rate_hz: float = option(
        1.0, unit="Hz", config="navigate.eval_rate_hz", help="evaluation epochs per second"
    )
    seed: int | None = option(None, shown="the shard's", help="root seed")
    grade: str | None = option(None, shown="the shard's", help="grade of the filter tuning")
    odometer: str | None = option(
        None, config="companions.odometer", shown="none", help="odometer preset (abs, encoder)"
    )
    odometer_rate_hz: float | None = option(
        None, unit="Hz", config="companions.odometer_rate_hz", shown="the preset's",
        help="odometer epochs per second",
    )  # fmt: skip
    odometer_lever_b_m: tuple = option(
        (0.0, 0.0, 0.0), flag="--odometer-lever", metavar="X,Y,Z", unit="m", parse=_xyz,
        config="companions.odometer_lever_b_m", help="odometer point, body frame",
    )  # fmt: skip
    odometer_scale_state: bool = option(
        True, flag="--no-odometer-scale-state", config="companions.odometer_scale_state",
        help="no odometer scale-factor state (noise inflated by its prior instead)",
    )  # fmt: skip
    barometer: str | None = option(
        None, flag="--baro", config="companions.barometer", shown="none",
        help="barometer preset (bmp388, ms5611)",
    )  # fmt: skip
    barometer_rate_hz: float | None = option(
        None, flag="--baro-rate-hz", unit="Hz", config="companions.barometer_rate_hz",
        shown="the preset's", help="barometer epochs per second",
    )  # fmt: skip
    companion_draw: str = option(
        "ranges", choices=DRAWS, config="companions.draw",
        help="companion error levels drawn in the presets' ranges per sequence, or nominal",
    )  # fmt: skip
    intervals_parsed: tuple = field(default=(), repr=False)
    """``intervals`` as :class:`imugen.aid.scenarios.Interval` (set when made)."""

    def __post_init__(self):
        import numpy as np

        from imugen.aid import companions as CP
        from imugen.aid import scenarios as SC
        from imugen.core.errors import InputError

        def put(name, value):
            object.__setattr__(self, name, value)

        if self.scenario:
            if self.intervals or self.draw_kinds:
                raise InputError("--scenario", "give scenario specs or intervals/draw_kinds")
            for name, value in SC.parse_scenarios(self.scenario).items():
                put(name, tuple(value))
        ivs = tuple(
            iv if isinstance(iv, SC.Interval) else SC.Interval.from_config(iv, f"scenario[{n}]")
            for n, iv in enumerate(self.intervals)
        )
        put("intervals_parsed", ivs)
        put("outage_durations_s", tuple(self.outage_durations_s))
        put("draw_kinds", tuple(self.draw_kinds))
        put("lever_arm_b_m", tuple(float(x) for x in self.lever_arm_b_m))
        for k in self.draw_kinds:
            if k not in SC.KINDS:
                raise InputError(
                    "scenarios.draw", f"unknown kind {k!r}; one of {', '.join(SC.KINDS)}"
                )
        if not self.align_speed_mps > 0:
            raise InputError("--align-speed", "must be > 0 m/s")
        if self.eval_rate_hz <= 0:
            raise InputError("--eval-rate-hz", "must be > 0")
        put("odometer_lever_b_m", tuple(float(x) for x in self.odometer_lever_b_m))
        if self.odometer is not None:
            CP.get_sensor("odometer", self.odometer)
        if self.barometer is not None:
            CP.get_sensor("barometer", self.barometer)
        if self.companion_draw not in DRAWS:
            raise InputError("--companion-draw", "must be ranges or nominal")
        if self.nhc_slip_sd_mps is not None:
            slip = np.atleast_1d(np.asarray(self.nhc_slip_sd_mps, float))
            if slip.shape not in ((1,), (2,)) or not np.all(np.isfinite(slip) & (slip >= 0)):
                raise InputError(
                    "--nhc-slip-sd", "expected LATERAL[,VERTICAL] m/s, finite and >= 0"
                )
            put("nhc_slip_sd_mps", tuple(float(x) for x in np.broadcast_to(slip, (2,))))


COMMANDS = {
    "aid": Command(
        AidOptions,
        "imugen.aid.stage:main",
        (
            argument("truth", help="truth Parquet"),
            argument("shard", help="shard Parquet written by `imugen simulate`"),
            argument(
                "--gnss-out", required=True, help="GNSS epochs Parquet (+ .labels/.intervals)"
            ),
            argument("-o", "--output", required=True, help="aided navigation-error Parquet"),
            argument("--companions-out", help="companion-sensor Parquet (+ .labels)"),
            argument(
                "--correction-in",
                help="a learner's IMU correction Parquet (imugen.tables.imu_correction), "
                "subtracted from the increments before the filter",
            ),
            argument(
                "--correction-out",
                help="IMU correction Parquet: what the filter removed from each increment "
                "(the filter-aware target is the shard's effective error minus it)",
            ),
            argument(
                "--estimates-out",
                help="filter-estimates Parquet (imugen.tables.filter_estimates): the filter's "
                "biases, scale factors, cross-coupling, attitude, velocity, position and the "
                "1-sigma of every state at every filter epoch",
            ),
            argument(
                "--learned-in",
                help="learned-measurements Parquet (imugen.tables.learned): body-frame velocity "
                "with its covariance and/or NHC variances per sequence and filter epoch",
            ),
        ),
    )
}
