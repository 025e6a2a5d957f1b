# The frozen GNSS-denied benchmark (config/benchmark.yaml, docs/benchmark.md): a reference
# network trained on the stream of the training routes (rule learn_train), its IMU correction
# of every evaluated shard (learn_correct), the aided filter on the corrected IMU
# (aid_learned, `imugen aid --correction-in`), its metrics (evaluate_learned, `imugen
# evaluate`, as the evaluate rule), and one table and figure over the validation and test
# routes beside free inertial and the aided filter on the raw IMU (benchmark_table).
BENCH = config.get("benchmark")
if BENCH:
    _split = {r: s for s in ("train", "validation", "test") for r in BENCH.get(s, [])}
    _named = [r for s in ("train", "validation", "test") for r in BENCH.get(s, [])]
    if len(_named) != len(set(_named)):
        _twice = sorted({r for r in _named if _named.count(r) > 1})
        raise WorkflowError(f"imugen: error: benchmark: routes {_twice} are in two splits")
    _unknown = sorted(r for r in _split if r not in config["routes"])
    if _unknown:
        raise WorkflowError(f"imugen: error: benchmark: routes {_unknown} are not under `routes`")
    _missing = sorted(
        str(config["routes"][r]["file"])
        for r in _split
        if not Path(config["routes"][r]["file"]).is_file()
    )
    if _missing:
        raise WorkflowError(
            f"imugen: error: benchmark: route file {_missing[0]} not found (the benchmark's "
            "routes are the shared trajectories: check ../shared out beside this repository)"
        )
    if not (AID_ON and WRITE_IMU):
        raise WorkflowError(
            "imugen: error: benchmark: needs gnss.enabled: true and simulate.write_imu: true"
        )
    BENCH_EVAL = [*BENCH.get("validation", []), *BENCH["test"]]
    BENCH_MODEL = BENCH["model"]
    BENCH_DIR = f"{layout.RESULTS}/benchmark"

    rule learn_train:
        input:
            truth=[layout.truth(r) for r in BENCH["train"]],
        output:
            f"{BENCH_DIR}/model/{{grade}}.pt",
        params:
            code=code_digest("imugen.learn.stage:main_train"),
            opts=" ".join(
                f"--{k.replace('_', '-')}={BENCH_MODEL[k]!r}"
                for k in ("steps", "batch_size", "windows_per_sequence", "window", "width",
                          "learning_rate")
            ),  # fmt: skip
            seed=SIM["seed"],
        threads: 1
        log:
            "logs/benchmark/learn_train/{grade}.log",
        shell:
            "imugen learn train {input.truth:q} --output={output:q} --grade={wildcards.grade} "
            "--seed={params.seed} {params.opts} --threads={threads} > {log:q} 2>&1"

    rule learn_correct:
        input:
            model=rules.learn_train.output[0],
            shard=layout.shard("imu"),
        output:
            temp(bench_shard("correction")),
        params:
            code=code_digest("imugen.learn.stage:main_correct"),
            smooth=float(BENCH_MODEL["smooth_s"]),
        log:
            "logs/{route}/benchmark/learn_correct/{grade}/shard-{shard}.log",
        shell:
            "imugen learn correct {input.model:q} {input.shard:q} --output={output:q} "
            "--smooth-s={params.smooth!r} > {log:q} 2>&1"

    rule aid_learned:
        input:
            truth=rules.truth.output[0],
            shard=layout.shard("imu"),
            correction=rules.learn_correct.output[0],
            grade=grade_files,
        output:
            gnss=temp(bench_shard("gnss")),
            labels=temp(layout.sidecar(bench_shard("gnss"), "labels")),
            intervals=temp(layout.sidecar(bench_shard("gnss"), "intervals")),
            aided=bench_shard("aided"),
            companions=temp(bench_shard("companions")),
            companion_labels=temp(
                layout.sidecar(bench_shard("companions"), "labels")
            ),
        params:
            code=code_digest("imugen.aid.stage"),
            opts=aid_opts,
            grade=grade_arg,
            eval_rate_hz=config["navigate"]["eval_rate_hz"],
        log:
            "logs/{route}/benchmark/aid_learned/{grade}/shard-{shard}.log",
        shell:
            "imugen aid {input.truth:q} {input.shard:q} --gnss-out={output.gnss:q} "
            "--output={output.aided:q} --companions-out={output.companions:q} "
            "--correction-in={input.correction:q} --grade={params.grade:q} "
            "--eval-rate-hz={params.eval_rate_hz} {params.opts} > {log:q} 2>&1"

    rule evaluate_learned:
        input:
            truth=rules.truth.output[0],
            nav=shard_paths("nav"),
            aided=lambda wc: [
                bench_shard("aided", s).format(route=wc.route, grade=wc.grade) for s in SHARDS
            ],
        output:
            f"{layout.route_dir()}/benchmark/metrics/{{grade}}.parquet",
        params:
            code=code_digest("imugen.evaluate.stage"),
        log:
            "logs/{route}/benchmark/evaluate_learned/{grade}.log",
        shell:
            "imugen evaluate {input.truth:q} {input.nav:q} --output={output:q} "
            "--grade={wildcards.grade} --aided {input.aided:q} > {log:q} 2>&1"

    rule benchmark_table:
        input:
            aided=expand(rules.evaluate.output[0], route=BENCH_EVAL, grade=GRADES),
            learned=expand(rules.evaluate_learned.output[0], route=BENCH_EVAL, grade=GRADES),
        output:
            csv=f"{BENCH_DIR}/table.csv",
            md=f"{BENCH_DIR}/table.md",
            figure=report(
                [f"{BENCH_DIR}/figure.{ext}" for ext in FIG["formats"]],
                caption="../report/benchmark.rst",
                category="Benchmark",
                labels={"figure": "GNSS-denied benchmark"},
            ),
        params:
            code=code_digest("imugen.learn.stage:main_table"),
            pairs=" ".join(
                f"--{kind}={shlex.quote(f'{r},{g}={path}')}"
                for kind, rule_ in (("aided", rules.evaluate), ("learned", rules.evaluate_learned))
                for r in BENCH_EVAL
                for g in GRADES
                for path in [rule_.output[0].format(route=r, grade=g)]
            ),
            splits=" ".join(f"--split={r}={_split[r]}" for r in BENCH_EVAL),
            durations=",".join(f"{float(d)!r}" for d in BENCH["outages_s"]),
            formats=" ".join(FIG["formats"]),
            dpi=FIG["dpi"],
        log:
            "logs/benchmark/table.log",
        shell:
            "imugen learn table --output={BENCH_DIR}/table --figure={BENCH_DIR}/figure "
            "{params.pairs} {params.splits} --durations={params.durations} "
            "--formats {params.formats} --dpi={params.dpi} > {log:q} 2>&1"

