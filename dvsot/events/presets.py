"""The sensor model's presets and which EventParams fields its stages are (no numpy, no numba: scene files read it).

The stages themselves are dvsot.events.sensor's; docs/events.md ("The sensor model") gives each preset's sources.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from dvsot.events import EventParams

V2E_DARK = 20.0 / 255.0  # v2e's intensity offset, 20 DN of 255: its lin-log knee and its inten01 = (DN + 20) / 275

# Photoreceptor noise (Graca and Delbruck 2021, arXiv:2109.08640, Fig. 3, as v2e fits it in v2ecore/emulator_utils.py,
# compute_photoreceptor_noise_voltage): log10(threshold / noise RMS) as a cubic in x = log10(ON noise events per second
# per Hz of the noise's 3 dB bandwidth), highest power first
PHOTORECEPTOR_NOISE_FIT = (-0.0026, -0.036, -0.1949, 0.321)
PHOTORECEPTOR_NOISE_FIT_RANGE = (1e-5, 1.0)  # the ON rates per Hz of bandwidth the fit covers (x from -5 to 0)

# The fields of the stages, each off at its default: the `ideal` model sets none of them.
SENSOR_FIELDS = ("linlog_intensity", "lowpass_order", "lowpass_cutoff_hz", "photoreceptor_noise_hz",
                 "shot_noise_bright_factor",
                 "leak_spread_decades", "leak_period_cv", "hot_pixel_fraction", "hot_pixel_hz", "latency_us",
                 "latency_jitter_us", "readout_limit_hz")

# Presets: the EventParams fields each one sets (the others keep their defaults); sources in docs/events.md.
PRESETS: dict[str, dict] = {
    "ideal": {},
    # v2e's --dvs_params clean (v2ecore/emulator.py, set_dvs_params), with its lin-log photoreceptor
    "clean": dict(cp=0.2, cn=0.2, sigma_cp=0.02, sigma_cn=0.02, linlog_intensity=V2E_DARK),
    # v2e's --dvs_params noisy; its leak jitter is per frame on the leak current, which leaves periods
    # nearly regular: a period CV of 0.1 here
    "noisy": dict(cp=0.2, cn=0.2, sigma_cp=0.05, sigma_cn=0.05, linlog_intensity=V2E_DARK, lowpass_order=1,
                  lowpass_cutoff_hz=30.0, shot_noise_hz=5.0, shot_noise_bright_factor=0.25, leak_hz=0.1,
                  leak_spread_decades=0.1, leak_period_cv=0.1),
    # iniVation DAVIS346: contrast sensitivity 14.3 % ON / 22.5 % OFF, 12 Meps readout, ~20 us latency
    "davis346": dict(cp=0.134, cn=0.203, sigma_cp=0.03, sigma_cn=0.03, linlog_intensity=V2E_DARK, lowpass_order=1,
                     lowpass_cutoff_hz=300.0, refractory_us=100.0, shot_noise_hz=0.5, shot_noise_bright_factor=0.25,
                     leak_hz=0.1, leak_spread_decades=0.1, leak_period_cv=0.1, hot_pixel_fraction=1e-4,
                     hot_pixel_hz=100.0, latency_us=20.0, latency_jitter_us=10.0, readout_limit_hz=12e6,
                     readout_fifo_events=4096),
    # Prophesee Gen4 class (Gen4 CD / IMX636, 1280x720): 1.066 Geps readout; IEBCS's latency and jitter
    "gen4": dict(cp=0.22, cn=0.22, sigma_cp=0.03, sigma_cn=0.03, linlog_intensity=V2E_DARK, lowpass_order=1,
                 lowpass_cutoff_hz=1000.0, refractory_us=50.0, shot_noise_hz=0.1, shot_noise_bright_factor=0.25,
                 leak_hz=0.05, leak_spread_decades=0.2, leak_period_cv=0.1, hot_pixel_fraction=1e-5,
                 hot_pixel_hz=100.0, latency_us=200.0, latency_jitter_us=50.0, readout_limit_hz=1.066e9,
                 readout_fifo_events=16384),
}


def sensor_on(params: EventParams) -> bool:
    """True if any stage beyond the ideal model is on (then EventSimulator runs inside a SensorModel)."""
    fields = type(params).model_fields
    return any(getattr(params, name) != fields[name].default for name in SENSOR_FIELDS)


def expand_preset(values: dict) -> dict:
    """The preset named in values ('ideal' if none) under the values given: each given field overrides the preset's."""
    name = values.get("preset", "ideal")
    if not isinstance(name, str) or name not in PRESETS:
        raise ValueError(f"preset {name!r} is unknown (known: {', '.join(PRESETS)})")
    return {**PRESETS[name], **values}
