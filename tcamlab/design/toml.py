"""The protocol file: ``NAME.next.toml``, the experiment's sample and rig with a ``[protocol]``
table the lab follows and the virtual rig runs (:func:`tcamlab.rig.simulate`)."""

from __future__ import annotations

from tcamlab.config import dumps_toml

__all__ = ["protocol_toml", "KEY_DOCS", "COPIED"]

COPIED = ("kind", "title", "notes", "runs", "sample", "rig", "columns")
"""Top-level keys copied from the experiment file (``runs``: its runs so far; add the new
runs' files there once they are made)."""

KEY_DOCS = {
    "kind": "rig kind the protocol is for",
    "loads_g": "hanging loads [g]; runs cycle through them (static, dynamic)",
    "oven": '"heating" (set points up) or "heat-cool" (up, then back down) (static)',
    "temperature_C": "first and last oven set point [degC] (static)",
    "step_C": "oven set point step [K], dividing the range (static)",
    "dwell_s": "dwell at each oven set point before the reading (static) or at each pull level (sensing) [s]",
    "voltages_V": "step voltages [V]; runs cycle through them (dynamic)",
    "pulse_s": "length of each voltage pulse [s] (dynamic)",
    "pulses": "pulses per run, a train when above 1 (dynamic)",
    "period_s": "start-to-start time of the pulses of a train [s], longer than pulse_s; default 2 pulse_s + 2 s (dynamic)",
    "duration_s": "logged duration of a run at 100 Hz [s], the first pulse 0.5 s in; default 10 s or the train's end + 9 s (dynamic)",
    "pull_mm": "largest elongation of the pull, a whole number of steps [mm] (sensing)",
    "step_mm": "actuator step between pull levels [mm] (sensing)",
    "speeds_mm_per_s": "actuator speeds between levels [mm/s]; runs cycle through them (sensing)",
    "cycles": "loading-unloading cycles per run, each 0 up to pull_mm and back to 0 (sensing)",
    "cable_mm": "largest cable pull of the protocol, a whole number of steps [mm] (curvature; each row logs its own pull as cable_mm)",
    "cable_step_mm": "cable pull step between bending levels [mm] (curvature)",
    "probe_V": "probe voltages at rest and between heating phases [V]; runs cycle through them (selfsensing)",
    "rider_g": "mass of the rider put on the hanger during the run [g]; negative: taken off (selfsensing)",
    "rider_s": "when the rider goes on [s]: a time, or [first, last] for a uniform random time (selfsensing)",
    "rest_s": "length of the rest at the probe that starts the run [s] (selfsensing)",
    "steps_s": "length of the voltage steps segment, each step on half of its share [s] (selfsensing)",
    "pwm_s": "length of the PWM segment [s] (selfsensing)",
    "sine_s": "length of the sine segment [s] (selfsensing)",
    "chirp_s": "length of the chirp segment [s] (selfsensing)",
    "hold_s": "length of the held probe after the chirp [s]; 0: none (selfsensing)",
    "ripple_V": "amplitude of a square ripple on the probe after the rest [V]; 0: none (selfsensing)",
    "ripple_Hz": "frequency of the probe ripple [Hz] (selfsensing)",
    "runs": "runs to make",
    "channels": "quantities to log, by tcamlab's column names; a log with headers of its own maps them in "
    "[columns], per run where they differ from the earlier runs' (docs: data contract)",
}
"""What each ``[protocol]`` key means, with its unit (written as a comment beside it)."""


def _value(v) -> str:
    line = dumps_toml({"x": v}).strip()
    return line.split("=", 1)[1].strip()


def protocol_toml(raw: dict, table: dict, header: str) -> str:
    """The text of a protocol file.

    Parameters
    ----------
    raw : dict
        The experiment file as parsed (:attr:`tcamlab.config.Experiment.raw`).
    table : dict
        The ``[protocol]`` table.
    header : str
        Comment lines at the top (why this protocol).
    """
    doc = {k: raw[k] for k in COPIED if k in raw}
    body = dumps_toml(doc)
    lines = ["[protocol]"]
    for k, v in table.items():
        lines.append(f"{k} = {_value(v)}  # {KEY_DOCS.get(k, '')}".rstrip(" #"))
    top = "".join(f"# {x}".rstrip() + "\n" for x in header.splitlines())
    return top + "\n" + body.rstrip() + "\n\n" + "\n".join(lines) + "\n"
