"""Pictures built on the warpratchet API: rerun recordings and the paper's figures.

Run as ``python -m viz <command>``: ``record`` (archive -> .rrd), ``scenes`` (the paper's
phase-space scenes as recordings), ``figures`` (the paper's figures as PNG and PDF).
"""
