"""Hydra configs of ``psbench``, loaded from ``pkg://psbench.conf``.

``config.yaml`` holds Hydra's own settings; the run parameters and harness settings
are generated from the run spec (:mod:`psbench.harness.spec`) into the ConfigStore
node it lists first.
"""
