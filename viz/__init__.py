"""Pictures built on the warpratchet API: the paper's figures, rerun recordings and the validation report.

Run as ``python -m viz <command>`` from a checkout, or ``python -m warpratchet_viz <command>``
where the package is installed (pyproject.toml installs this folder under that name, so that it
claims no generic top-level name): ``figures`` (the paper's figures as PNG and PDF, the package
:mod:`.figures`), ``scenes`` (the paper's phase-space scenes as rerun recordings), ``record``
(archive -> .rrd) and ``report`` (``docs/validation.md`` from the figures' sweep files). Imports
inside the package are relative, so either name works; every parameter of the paper comes from
:mod:`warpratchet.paper`.
"""
