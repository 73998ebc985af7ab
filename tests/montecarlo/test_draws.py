"""Draws against the distributions they claim, with confidence-based tolerances.

The draws of N runs are N independent samples of each dispersion (independent PCG64 streams, one per
(master seed, run, dispersion)). Each check compares a sample statistic with its exact value from
scipy.stats (an independent implementation) within Z = 5 standard errors: for a fresh seed such a
check would fail with probability < 6e-7 (two-sided normal tail), and the seeds are fixed, so the
tests are deterministic. Kolmogorov-Smirnov and chi-square tests must not reject at the 1e-4 level.
"""

import textwrap

import numpy as np
import pytest
from scipy import stats

from shell.montecarlo.campaign import CampaignError, parse_campaign
from shell.montecarlo.draws import draw_run, standard_normals

N = 4000
Z = 5.0


def campaign(tmp_path, dispersions: str, correlations: str = "", seed: int = 11):
    (tmp_path / "s.yaml").write_text("models: {c: {type: Constant, config: {unit: m}}}\nstop: {time: 1 s}\n")
    text = f"scenario: s.yaml\nruns: {N}\nseed: {seed}\ndispersions:\n" + textwrap.indent(
        textwrap.dedent(dispersions), "  ") + textwrap.dedent(correlations)
    return parse_campaign(text, str(tmp_path / "c.yaml"), validate=False)


def samples(c) -> dict:
    runs = [c.draws(i) for i in range(N)]
    return {d.path: np.array([r[d.path] for r in runs]) for d in c.dispersions}


def check_moments(x: np.ndarray, reference) -> None:
    """Sample mean and variance of x within Z standard errors of the reference's exact values."""
    mean, var, _, excess_kurtosis = (float(v) for v in reference.stats(moments="mvsk"))
    n = x.size
    se_mean = np.sqrt(var / n)
    # variance of the sample variance: (mu4 - sigma^4 (n-3)/(n-1)) / n, mu4 = (kurtosis + 3) sigma^4
    se_var = np.sqrt(((excess_kurtosis + 3) * var ** 2 - var ** 2 * (n - 3) / (n - 1)) / n)
    assert abs(x.mean() - mean) < Z * se_mean, (x.mean(), mean, se_mean)
    assert abs(x.var(ddof=1) - var) < Z * se_var, (x.var(ddof=1), var, se_var)
    assert stats.kstest(x, reference.cdf).pvalue > 1e-4


def test_normal_per_axis_in_units(tmp_path):
    c = campaign(tmp_path, """
        c.value: {distribution: normal, mean: "[1, 2, 3] m", sigma: "[10, 20, 30] cm"}
    """)
    x = samples(c)["c.value"]
    assert x.shape == (N, 3) and c.dispersions[0].unit == "m"
    for k in range(3):
        check_moments(x[:, k], stats.norm(k + 1, 0.1 * (k + 1)))


def test_uniform(tmp_path):
    c = campaign(tmp_path, "c.value: {distribution: uniform, low: -3 deg, high: 5 deg}\n")
    x = samples(c)["c.value"][:, 0]
    check_moments(x, stats.uniform(-3, 8))
    assert x.min() >= -3 and x.max() <= 5


def test_truncated_normal_stays_in_bounds(tmp_path):
    c = campaign(tmp_path, "c.value: {distribution: truncated_normal, mean: 10, sigma: 2, low: 7, high: 15}\n")
    x = samples(c)["c.value"][:, 0]
    check_moments(x, stats.truncnorm((7 - 10) / 2, (15 - 10) / 2, loc=10, scale=2))
    assert x.min() >= 7 and x.max() <= 15


def test_truncated_normal_far_tail_is_exact():
    """Normals beyond 8.3 sigma (where Phi(z) rounds to 1) still map inside the bounds, by the upper tail."""
    from shell.montecarlo.draws import Dispersion

    d = Dispersion("x", "truncated_normal", (), "", {k: np.array(v) for k, v in
                                                    dict(mean=0.0, sigma=1.0, low=-1.0, high=12.0).items()})
    z = np.array([-9.0, 0.0, 9.0, 10.0])
    expected = stats.truncnorm.ppf(stats.norm.cdf(z[:2]), -1.0, 12.0)
    np.testing.assert_allclose(d.transform(z)[:2], expected, rtol=1e-12)
    # upper tail: P(X > x) = P(Z > z) with the truncated survival function (exact, no rounding to 1)
    np.testing.assert_allclose(stats.truncnorm.sf(d.transform(z)[2:], -1.0, 12.0), stats.norm.sf(z[2:]), rtol=1e-8)


def test_lognormal(tmp_path):
    c = campaign(tmp_path, "c.value: {distribution: lognormal, median: 2 kg, log_sigma: 0.3}\n")
    x = samples(c)["c.value"][:, 0]
    check_moments(x, stats.lognorm(0.3, scale=2.0))


def test_discrete_choice_frequencies(tmp_path):
    c = campaign(tmp_path, "c.value: {distribution: choice, choices: [1 m, 2 m, 3 m], probabilities: [0.2, 0.5, 0.3]}\n")
    index = samples(c)["c.value"][:, 0].astype(int)
    counts = np.bincount(index, minlength=3)
    assert stats.chisquare(counts, N * np.array([0.2, 0.5, 0.3])).pvalue > 1e-4
    assert c.overrides(0)[0] == f"c.value={['1 m', '2 m', '3 m'][index[0]]}"


@pytest.mark.parametrize("rho", [0.8, -0.5])
def test_correlated_pair(tmp_path, rho):
    c = campaign(tmp_path, """
        a.value: {distribution: normal, mean: "[0, 0]", sigma: "[1, 2]"}
        b.value: {distribution: lognormal, median: "[1, 1]", log_sigma: 0.5}
    """, f"correlations:\n  - {{between: [a.value, b.value], coefficient: {rho}}}\n")
    x = samples(c)
    a, b = x["a.value"], np.log(x["b.value"])  # ln of a log-normal value is its underlying normal
    check_moments(a[:, 1], stats.norm(0, 2))     # marginals unchanged by the correlation
    check_moments(x["b.value"][:, 0], stats.lognorm(0.5))
    for k in range(2):
        r = np.corrcoef(a[:, k], b[:, k])[0, 1]
        # Fisher: atanh(r) is normal with standard error 1/sqrt(N - 3)
        assert abs(np.arctanh(r) - np.arctanh(rho)) < Z / np.sqrt(N - 3), (r, rho)
    cross = np.corrcoef(a[:, 0], b[:, 1])[0, 1]
    assert abs(np.arctanh(cross)) < Z / np.sqrt(N - 3)  # components are correlated axis by axis only


def test_correlation_matrix(tmp_path):
    matrix = [[1, 0.5, -0.3], [0.5, 1, 0.2], [-0.3, 0.2, 1]]
    c = campaign(tmp_path, """
        a.value: {distribution: normal, mean: 0, sigma: 1}
        b.value: {distribution: normal, mean: "[0, 0]", sigma: 1}
    """, f"correlations:\n  - {{between: [a.value, b.value], matrix: {matrix}}}\n")
    x = samples(c)
    values = np.column_stack([x["a.value"][:, 0], x["b.value"]])
    r = np.corrcoef(values.T)
    assert np.all(np.abs(np.arctanh(r[np.triu_indices(3, 1)]) - np.arctanh(np.array(matrix)[np.triu_indices(3, 1)]))
                  < Z / np.sqrt(N - 3))


def test_draws_depend_only_on_seed_run_and_name(tmp_path):
    one = campaign(tmp_path, "a.value: {distribution: normal, mean: 0, sigma: 1}\n")
    two = campaign(tmp_path, """
        z.value: {distribution: uniform, low: 0, high: 1}
        a.value: {distribution: normal, mean: 0, sigma: 1}
    """)
    for i in (0, 17, 3999):
        assert one.draws(i)["a.value"].tobytes() == two.draws(i)["a.value"].tobytes()
    assert one.draws(5)["a.value"][0] != one.draws(6)["a.value"][0]
    other_seed = campaign(tmp_path, "a.value: {distribution: normal, mean: 0, sigma: 1}\n", seed=12)
    assert other_seed.draws(5)["a.value"][0] != one.draws(5)["a.value"][0]
    # run i's stream is the i-th child of SeedSequence(master), spawned again by the dispersion's name
    child = np.random.SeedSequence(11).spawn(18)[17]
    assert child.spawn_key == (17,)
    assert standard_normals(11, 17, "a.value", 1)[0] == one.draws(17)["a.value"][0]


def test_draw_run_without_dispersions_is_empty():
    assert draw_run([], [], 3, 0) == {}


@pytest.mark.parametrize("spec, message", [
    ("c.value: {distribution: gaussian, mean: 0, sigma: 1}", "c.yaml:5: dispersions.c.value.distribution: expected one of"),
    ("c.value: {distribution: normal, mean: 0}", "c.yaml:5: dispersions.c.value: a normal dispersion needs ['mean', 'sigma']; 'sigma' is missing"),
    ("c.value: {distribution: normal, mean: 0, sigma: -1}", "c.yaml:5: dispersions.c.value.sigma: expected a non-negative"),
    ("c.value: {distribution: uniform, low: 2 m, high: 1 m}", "dispersions.c.value.high: expected high > low"),
    ("c.value: {distribution: normal, mean: 1 m, sigma: 1 s}", "dispersions.c.value.sigma:"),
    ("c.value: {distribution: normal, mean: 1 m, sigma: 1 cm, low: 0 m}", "'low' does not belong to a normal dispersion"),
    ("c.value: {distribution: choice, choices: [1, 2], probabilities: [0.5, 0.6]}", "summing to 1"),
    ("c.value: {distribution: lognormal, median: -1, log_sigma: 0.1}", "expected a positive median"),
    ("c.value: {distribution: normal, mean: \"[1, 2]\", sigma: \"[1, 2, 3]\"}", "do not fit one value shape"),
])
def test_dispersion_errors_name_file_line_and_key(tmp_path, spec, message):
    (tmp_path / "s.yaml").write_text("models: {c: {type: Constant}}\n")
    text = f"scenario: s.yaml\nruns: 3\nseed: 1\ndispersions:\n  {spec}\n"
    with pytest.raises(CampaignError) as info:
        parse_campaign(text, str(tmp_path / "c.yaml"), validate=False)
    assert message in str(info.value)


def test_correlation_errors(tmp_path):
    base = "a.value: {distribution: normal, mean: 0, sigma: 1}\nb.value: {distribution: normal, mean: \"[0, 0]\", sigma: 1}\n"
    with pytest.raises(CampaignError, match=r"c.yaml:9: correlations\[0\].matrix: the correlation matrix is not "
                                            r"positive definite"):
        campaign(tmp_path, base, "correlations:\n  - between: [a.value, b.value]\n"
                                 "    matrix: [[1, 0.9, 0.9], [0.9, 1, -0.9], [0.9, -0.9, 1]]\n")
    with pytest.raises(CampaignError, match="sizes differ"):
        campaign(tmp_path, base, "correlations:\n  - {between: [a.value, b.value], coefficient: 0.5}\n")
    with pytest.raises(CampaignError, match="'c.value' is not a dispersion"):
        campaign(tmp_path, base, "correlations:\n  - {between: [a.value, c.value], coefficient: 0.5}\n")


def test_truncated_normal_quantiles_equal_scipys_bit_for_bit():
    """The draws' quantile function (scipy's kernel without the public method's argument handling) against
    scipy.stats.truncnorm.ppf: bounds on both sides of zero and far out, probabilities from the normal tails down to
    underflow (q = 0) and up to one half, as a run's draws give them."""
    from scipy import special, stats

    from shell.montecarlo.draws import truncated_normal_ppf

    rng = np.random.default_rng(7)
    for _ in range(2000):
        a = rng.uniform(-12.0, 6.0, 4)
        b = a + rng.uniform(1e-3, 12.0, 4)
        z = rng.standard_normal(4) * rng.choice([1.0, 10.0, 40.0])
        q = np.where(z > 0, special.ndtr(-z), special.ndtr(z))
        assert truncated_normal_ppf(q, a, b).tobytes() == stats.truncnorm.ppf(q, a, b).tobytes(), (q, a, b)
