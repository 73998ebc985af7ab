"""Small scenes and campaigns for the Monte Carlo tests (runs of a few milliseconds each)."""

import textwrap

import pytest

# A ramp x' = v sampled at 10 Hz with Gaussian noise: dispersed rate v and noise sigma, noise from the
# sensor's random stream (seeded [master, i] in run i).
NOISY_RAMP = """
name: noisy_ramp
seed: 0
models:
  rate: {type: Constant, config: {unit: m/s}, parameters: {value: 1 m/s}}
  position: {type: Integrator, config: {unit: m}}
  sensor: {type: NoisySampler, rate: 10 Hz, config: {unit: m}, parameters: {sigma: 0.01 m}}
connections:
  - rate.y -> position.u
  - position.y -> sensor.u
integrator: {method: rk4, step: 0.01 s}
stop: {time: 2 s}
log: {rate: 10 Hz, signals: [sensor.y]}
"""

RAMP_CAMPAIGN = """
name: ramp_campaign
scenario: ramp.yaml
runs: {runs}
seed: 7
dispersions:
  rate.value: {{distribution: normal, mean: 100 cm/s, sigma: 10 cm/s}}
  sensor.sigma: {{distribution: uniform, low: 1 mm, high: 5 mm}}
metrics:
  final_position: {{signal: position.y, statistic: final, unit: m}}
  peak_reading: {{signal: sensor.y, statistic: max}}
keep: [sensor.y]
"""


@pytest.fixture
def write(tmp_path):
    """write(name, text) -> path of a dedented file in the test's directory."""

    def put(name, text):
        path = tmp_path / name
        path.write_text(textwrap.dedent(text))
        return path

    return put


@pytest.fixture
def ramp_campaign(write):
    """Path of a campaign of ``runs`` runs over the noisy ramp."""

    def make(runs=6, extra=""):
        write("ramp.yaml", NOISY_RAMP)
        return write("ramp_campaign.yaml", RAMP_CAMPAIGN.format(runs=runs) + textwrap.dedent(extra))

    return make
