"""A Dask worker preload for tests: the scene named by DVSOT_TEST_FAIL fails inside dvsot.pipeline.generate.generate."""

import os

import dvsot.pipeline.generate as _generate

if not getattr(_generate.generate, "injected", False):  # a preload may run more than once per process
    _real = _generate.generate

    def generate(cfg, *args, **kwargs):
        if cfg.name == os.environ.get("DVSOT_TEST_FAIL"):
            raise RuntimeError("injected failure")
        return _real(cfg, *args, **kwargs)

    generate.injected = True
    _generate.generate = generate
