"""``imugen serve``: a local web page in front of the Snakemake workflow (never a second engine).

A user uploads a route, sees it in plan view with its length, duration and candidate paths,
chooses vehicle, grades and the workflow options (a form generated from the same JSON schema
the workflow validates, ``workflow/schemas/config.schema.yaml``), starts the run, follows its
progress and log, cancels or re-runs it after a change (Snakemake reruns only what changed),
then sees the RMSE table, figures and Allan checks and downloads the data and the report.

Every run lives in its own folder ``WORKDIR/runs/<id>/`` (``input/`` the uploaded file under a
sanitized name, ``config/config.yaml``, ``results/``, ``logs/``, ``run.log``, ``state.json``);
the workflow runs there with ``snakemake -s <repo>/Snakefile -d <run folder>``. The page obeys
only the user who started it, from their own browser tab: :mod:`imugen.web.security`.
"""


def main(options) -> None:
    """``imugen serve`` (:class:`~imugen.web.options.ServeOptions`); needs Flask."""
    from imugen.core.errors import InputError

    try:
        from imugen.web.app import serve
    except ImportError:
        raise InputError("imugen serve", "needs Flask: pip install -e '.[web]'") from None
    serve(options.workdir, host=options.host, port=options.port, repo=options.repo)
