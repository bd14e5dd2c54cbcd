"""The compiled three-channel bank equals the reference channel filter, its
cross-covariance kernel equals its matrix-form reference, and its covariances
stay symmetric positive definite; the same input gives the same output."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from mavnav.bank import CHANNELS, PAIRS, ChannelBank, cross_kernel, cross_reference
from mavnav.channel import (GB, N_PAPER, N_STATES, AuxMeasurement, EpochInputs, Model, baro_gauss_markov,
                            gnss_gauss_markov, initial_state, state_process_noise, state_transition, step)
from mavnav.config import config_from_dict


def random_epochs(seed: int, n: int, p_baro=0.9, p_gnss=0.3, p_rng=0.5, p_restart=0.02, measured=False):
    """Random epochs; ``measured``: with the epoch builder's measured IMU and baro noise too."""
    rng = np.random.default_rng(seed)
    t = 0
    out = []
    for _ in range(n):
        dt = float(rng.uniform(0.005, 0.2))
        t += int(dt * 1e6)
        has_b = rng.random() < p_baro
        out.append(EpochInputs(
            t_us=t, dt_s=int(dt * 1e6) * 1e-6, dp_m=float(rng.normal(0, 0.01)), dv_mps=float(rng.normal(0, 0.1)),
            baro_m=float(rng.normal(0, 3)) if has_b else None,
            gnss=AuxMeasurement(float(rng.normal(0, 3)), float(rng.uniform(0.3, 5)), float(rng.uniform(0, 0.1)))
            if rng.random() < p_gnss else None,
            rng=AuxMeasurement(float(rng.normal(0, 3)), float(rng.uniform(0.05, 1)), float(rng.uniform(0, 0.05)))
            if rng.random() < p_rng else None,
            baro_restart=bool(has_b and rng.random() < p_restart),
            dv_var_m2ps2=float(rng.uniform(0, 0.05)) if measured else 0.0,
            baro_white_var_m2=float(rng.uniform(0, 0.2)) if measured and has_b else 0.0,
        ))
    return out


def cfg_gm(gm_sigma_m: float, gm_tau_s: float = 300.0):
    """Bias random walks on; the GNSS Gauss-Markov error state on (sigma > 0) or off."""
    return config_from_dict({"sensors": {"ins": {"bias_rw_mps2_per_sqrt_s": 0.001},
                                         "baro": {"bias_rw_m_per_sqrt_s": 0.01},
                                         "gnss": {"gm_sigma_m": gm_sigma_m, "gm_tau_s": gm_tau_s}}})


CFG = cfg_gm(3.0)
GM = pytest.mark.parametrize("gm_sigma_m", [3.0, 0.0], ids=["gm_on", "gm_off"])


@pytest.mark.simulation
@pytest.mark.slow
@GM
@pytest.mark.parametrize("measured", [False, True], ids=["model_noise", "measured_noise"])
@pytest.mark.parametrize("form", ["consistent", "printed"])
def test_bank_equals_reference_channels(form, gm_sigma_m, measured):
    cfg = cfg_gm(gm_sigma_m)
    cfg = cfg.model_copy(update={"filter": cfg.filter.model_copy(update={"accel_noise_form": form})})
    model = Model.from_config(cfg)
    assert model.gnss_gm_sigma_m == gm_sigma_m and model.gnss_gm_tau_s == 300.0
    bank = ChannelBank(model)
    bank.start(0, 0.5)
    ref = {k: initial_state(model, 0, 0.5) for k in CHANNELS}
    for ep in random_epochs(7, 3000, measured=measured):
        # the chi-square gates' predictions, before the step
        pred_aux = {c: bank.predicted_aux(c, ep, a) for c, a in ((0, ep.gnss), (1, ep.rng)) if a is not None}
        pred_baro = [bank.predicted_baro(c, ep) for c in range(len(CHANNELS))]
        out = bank.step(ep)
        for c, k in enumerate(CHANNELS):
            ref[k], r = step(k, ref[k], ep, model)
            np.testing.assert_allclose(bank.x[c], ref[k].x, rtol=1e-9, atol=1e-9)
            np.testing.assert_allclose(bank.P[c], ref[k].P, rtol=1e-8, atol=1e-10 * np.abs(ref[k].P).max())
            assert out.dof[c] == r.dof
            assert math.isclose(out.nis[c], r.nis, rel_tol=1e-8, abs_tol=1e-12)
            used = [i for i, name in ((0, "baro"), (1, "gnss" if k == "gnss" else "rng")) if name in r.rows]
            np.testing.assert_allclose(out.innovation[c, used], r.innovation, rtol=1e-9, atol=1e-9)
            if c in pred_aux:
                np.testing.assert_allclose(pred_aux[c], (out.innovation[c, 1], out.innovation_var[c, 1]), rtol=1e-9)
            if "baro" in r.rows:
                np.testing.assert_allclose(pred_baro[c], (out.innovation[c, 0], out.innovation_var[c, 0]), rtol=1e-9)
        if gm_sigma_m == 0.0:  # the GNSS error state stays exactly 0 with no variance
            assert not bank.x[:, GB].any() and not bank.P[:, GB].any() and not bank.Pc[:, GB].any()
            assert not bank.Pc[:, :, GB].any()
    if gm_sigma_m > 0:  # the GNSS channel has learnt something of b_g; the others have not
        assert bank.P[0, GB, GB] < 0.9 * gm_sigma_m**2
        assert bank.x[1, GB] == bank.x[2, GB] == 0.0
        np.testing.assert_allclose(bank.P[1:, GB, GB], gm_sigma_m**2, rtol=1e-9)


def test_bank_detects_a_different_filter():
    """The comparison is sharp: a different baro noise model shows."""
    model = Model.from_config(CFG)
    other = Model.from_config(config_from_dict({"sensors": {"baro": {"sigma_bb_m": 1.1}}}))
    bank = ChannelBank(other)
    bank.start(0, 0.5)
    ref = initial_state(model, 0, 0.5)
    for ep in random_epochs(8, 200):
        bank.step(ep)
        ref, _ = step("gnss", ref, ep, model)
    assert not np.allclose(bank.P[0], ref.P, rtol=1e-6)


@pytest.mark.slow
@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), p_baro=st.floats(0.0, 1.0), p_gnss=st.floats(0.0, 1.0),
       gm_sigma_m=st.sampled_from([3.0, 0.0]))
def test_covariance_stays_spd_and_deterministic(seed, p_baro, p_gnss, gm_sigma_m):
    model = Model.from_config(cfg_gm(gm_sigma_m))
    n = N_STATES if gm_sigma_m > 0 else N_PAPER  # with the state off b_g has exactly zero variance
    eps = random_epochs(seed, 400, p_baro=p_baro, p_gnss=p_gnss)
    runs = []
    for _ in range(2):
        bank = ChannelBank(model)
        bank.start(0, 0.0)
        for ep in eps:
            bank.step(ep)
            assert np.allclose(bank.P, np.swapaxes(bank.P, 1, 2), rtol=0, atol=0)
        assert np.all(np.linalg.eigvalsh(bank.P[:, :n, :n]) > 0)
        runs.append((bank.x.copy(), bank.P.copy()))
    assert np.array_equal(runs[0][0], runs[1][0]) and np.array_equal(runs[0][1], runs[1][1])


def test_bank_refuses_non_finite_input_and_keeps_state():
    bank = ChannelBank(Model.from_config(CFG))
    bank.start(0, 0.0)
    x0 = bank.x.copy()
    from mavnav.errors import NonFiniteInputError

    with pytest.raises(NonFiniteInputError, match="rng.height_m"):
        bank.step(EpochInputs(t_us=20000, dt_s=0.02, dp_m=0.0, dv_mps=0.0, baro_m=0.0,
                              rng=AuxMeasurement(math.inf, 0.1, 0.0)))
    assert np.array_equal(bank.x, x0)


@pytest.mark.simulation
@pytest.mark.slow
@pytest.mark.parametrize("gm_sigma_m, gm_tau_s", [(0.0, 300.0), (3.0, 20.0)], ids=["white", "gauss_markov"])
def test_cross_covariances_match_monte_carlo(gm_sigma_m, gm_tau_s):
    """The variance of each channel difference is P_a + P_b - 2 P_ab: the
    normalised differences over seeded runs have unit variance; without the
    cross term they would look about twice as calm as they are. Also with a
    GNSS error that is white + Gauss-Markov (a short correlation time, so it
    moves within the 12 s runs) and the filters modelling it."""
    from tests.support.estimator import with_gnss_gauss_markov
    from mavnav.epochs import EpochBuilder, EpochStart
    from tests.support.synthetic import Schedule, TrueSensors, paper_flight

    # A regime where both aux channels lean on the shared baro+INS between
    # sparse fixes (slow baro noise, 2 Hz GNSS and rangefinder).
    sensors = TrueSensors(sigma_a_mps2=0.5, alpha_a_per_s=1.0, sigma_bb_m=3.0, gamma_bb_per_s=0.05,
                          sigma_z_m=0.5, sigma_rng_m=0.5)
    cfg = config_from_dict({
        "sensors": {"ins": {"sigma_a_mps2": 0.5, "bias_rw_mps2_per_sqrt_s": 0.0},
                    "baro": {"gamma_bb_per_s": 0.05, "sigma_bb_m": 3.0, "bias_rw_m_per_sqrt_s": 0.0},
                    # the filters' GNSS error model is the truth's
                    "gnss": {"sigma_z_m": 0.5, "use_v_acc": False, "gm_sigma_m": gm_sigma_m, "gm_tau_s": gm_tau_s},
                    "rangefinder": {"sigma_m": 0.5, "scale_sigma_frac": 0.0}},
        # the zero-mean prior: with the diffuse one the baro channel's height
        # error is one large draw per run and 30 runs cannot pin its mean
        "filter": {"height_prior": "p0",
                   "p0": {"height_m2": 100.0, "vel_m2ps2": 1.0, "baro_bias_m2": 100.0, "acc_bias_m2ps4": 0.04}},
    })
    model = Model.from_config(cfg)
    p0 = cfg.filter.p0
    z_with, z_without = {p: [] for p in range(3)}, {p: [] for p in range(3)}
    from mavnav.bank import PAIRS

    # the GNSS channel's error is largely one draw of b_g per run: more runs
    runs = 30 if gm_sigma_m == 0 else 120
    for seed in range(runs):
        rng = np.random.default_rng(seed)
        h0, v0, dh, da = rng.standard_normal(4) * np.sqrt([p0.height_m2, p0.vel_m2ps2, p0.baro_bias_m2, p0.acc_bias_m2ps4])
        s = TrueSensors(**{**sensors.__dict__, "baro_bias_m": dh, "acc_bias_mps2": da})
        flight = paper_flight(seed=seed, sensors=s, schedule=Schedule(duration_s=12.0, gnss_every=25, rng_every=25),
                              h0_m=h0, v0_mps=v0)
        samples = flight.samples
        if gm_sigma_m > 0:
            samples, _ = with_gnss_gauss_markov(samples, gm_sigma_m, gm_tau_s, seed=100 + seed)
        bank, builder = ChannelBank(model), EpochBuilder(cfg)
        n = 0
        for smp in samples:
            for ep in builder.push(smp):
                if isinstance(ep, EpochStart):
                    bank.start(ep.t_us, ep.baro_m)
                    continue
                bank.step(ep)
                n += 1
                if n % 40 or n < 100:
                    continue
                h_true, _ = flight.truth_at(ep.t_us)
                e = h_true - bank.x[:, 0]
                for p, (a, b) in enumerate(PAIRS):
                    d = e[a] - e[b]
                    var_without = bank.P[a, 0, 0] + bank.P[b, 0, 0]
                    var_with = var_without - 2 * bank.Pc[p, 0, 0]
                    z_with[p].append(d * d / var_with)
                    z_without[p].append(d * d / var_without)
    for p in range(3):
        m = np.mean(z_with[p])
        assert 0.8 < m < 1.2, (PAIRS[p], m)
    # the cross term matters for the pairs that share the baro most
    # without the cross term, the GNSS/rangefinder difference looks far calmer than it is
    if gm_sigma_m == 0:
        assert np.mean(z_without[0]) < 0.75


# ---------------------------------------------------------------- cross_kernel against its reference


def _kernel_scalars(model: Model, T: float, dv_var_m2ps2: float, baro_white_var_m2: float):
    """What ChannelBank.step hands cross_kernel, from the model (the test's own
    spelling of gamma_u^2: mavnav.channel.measurement_rows's baro row noise)."""
    g0, g1 = ChannelBank(model)._g(T, dv_var_m2ps2)
    phi_g, q_g = gnss_gauss_markov(T, model)
    phi_u, gamma_u = baro_gauss_markov(T, model)
    return dict(T=T, g0=g0, g1=g1, q_dh=model.baro_bias_rw_m_per_sqrt_s**2 * T,
                q_da=model.acc_bias_rw_mps2_per_sqrt_s**2 * T, phi_g=phi_g, q_g=q_g,
                gamma_u2=gamma_u * gamma_u + (1.0 + phi_u * phi_u) * baro_white_var_m2)


def _assert_cross_equal(got, want):
    np.testing.assert_allclose(got, want, rtol=1e-10, atol=1e-12 * max(np.abs(want).max(), 1e-300))


@pytest.mark.parametrize("seed", [0, 1, 2, 3, 4, 5, 6, 7])
def test_cross_kernel_equals_reference_on_random_inputs(seed):
    """Random SPD joint covariances (their off-diagonal blocks are the pairs'
    cross-covariances), random gains and rows of 0, 1 or 2 rows per channel,
    a random model and step: the compiled kernel is the matrix formula, with
    Phi and Bxx from the channel module (not the kernel's closed forms)."""
    rng = np.random.default_rng(seed)
    n = N_STATES
    model = Model.from_config(cfg_gm(float(rng.choice([0.0, 3.0])), float(rng.uniform(5.0, 500.0))))
    model = dataclasses.replace(model, sigma_a_mps2=float(rng.uniform(0.05, 2.0)),
                                alpha_a_per_s=float(rng.uniform(0.1, 5.0)),
                                sigma_bb_m=float(rng.uniform(0.1, 5.0)), gamma_bb_per_s=float(rng.uniform(0.01, 1.0)),
                                baro_bias_rw_m_per_sqrt_s=float(rng.uniform(0.0, 0.05)),
                                acc_bias_rw_mps2_per_sqrt_s=float(rng.uniform(0.0, 0.01)))
    T = float(rng.uniform(0.005, 0.2))
    dv_var = float(rng.choice([0.0, rng.uniform(0.0, 0.05)]))
    sc = _kernel_scalars(model, T, dv_var, float(rng.uniform(0.0, 0.2)))
    M = rng.standard_normal((3 * n, 3 * n))
    joint = M @ M.T + 1e-3 * np.eye(3 * n)  # SPD: the three channels' errors together
    Pc = np.array([joint[a * n:(a + 1) * n, b * n:(b + 1) * n] for a, b in PAIRS])
    dof = rng.integers(0, 3, size=len(CHANNELS)).astype(np.int64)
    K = rng.standard_normal((len(CHANNELS), n, 2))
    Fy = rng.standard_normal((len(CHANNELS), 2, n))
    Hr = rng.standard_normal((len(CHANNELS), 2, n))
    rb = rng.random((len(CHANNELS), 2)) < 0.7
    pairs = np.array(PAIRS, dtype=np.int64)
    Phi, Bxx = state_transition(T, model), state_process_noise(T, model, dv_var)
    Pc0 = Pc.copy()
    want = cross_reference(Pc, pairs, Phi, Bxx, sc["gamma_u2"], dof, K, Fy, Hr, rb)
    assert np.array_equal(Pc, Pc0)  # the reference leaves its input alone
    got = Pc.copy()
    cross_kernel(got, pairs, sc["T"], sc["g0"], sc["g1"], sc["q_dh"], sc["q_da"], sc["phi_g"], sc["q_g"],
                 sc["gamma_u2"], dof, K, Fy, Hr, rb)
    _assert_cross_equal(got, want)
    assert not np.allclose(got, Pc0)
    # the comparison is sharp: the shared baro noise shows where two baro rows meet
    shared = any(rb[a, r] and rb[b, s] for a, b in PAIRS for r in range(dof[a]) for s in range(dof[b]))
    other = cross_reference(Pc, pairs, Phi, Bxx, 2.0 * sc["gamma_u2"], dof, K, Fy, Hr, rb)
    assert np.allclose(other, want, rtol=1e-12, atol=0) != shared


@pytest.mark.parametrize("seed", [3, 11, 29])
@GM
def test_cross_kernel_equals_reference_over_a_run(seed, gm_sigma_m):
    """Step by step over a long irregular run (measured input noise, baro
    restarts, the baro switched off and on per channel, feedback between the
    channels), the bank's cross-covariances are the reference's propagation
    of the previous ones with the step's gains and rows."""
    model = Model.from_config(cfg_gm(gm_sigma_m))
    bank = ChannelBank(model)
    bank.start(0, 0.5)
    rng = np.random.default_rng(seed)
    shared_baro = 0
    for k, ep in enumerate(random_epochs(seed, 1500, measured=True)):
        if k % 50 == 0:
            bank.baro_on[:] = rng.random(len(CHANNELS)) < 0.8
        if k % 137 == 136:
            bank.feedback(2, [0, 1], np.array([0.5, 0.5]), inflation=4.0)
        Pc0 = bank.Pc.copy()
        bank.step(ep)
        sc = _kernel_scalars(model, ep.dt_s, ep.dv_var_m2ps2, ep.baro_white_var_m2)
        want = cross_reference(Pc0, PAIRS, state_transition(ep.dt_s, model),
                               state_process_noise(ep.dt_s, model, ep.dv_var_m2ps2), sc["gamma_u2"],
                               bank._dof, bank._K, bank._Fy, bank._Hr, bank._rb)
        _assert_cross_equal(bank.Pc, want)
        shared_baro += int(bank._rb[:, 0].sum() >= 2)
    assert shared_baro > 500  # most steps exercised the shared baro term


class _TwoCalls(ChannelBank):
    """The step as it was before step_kernel: bank_kernel, then cross_kernel, two calls."""

    def step(self, ep):
        import mavnav.bank as b

        saved = b.step_kernel

        def two(x, P, baro_prev, T, dp, dv, g0, g1, q_dh, q_da, phi_g, q_g, has_baro, baro_on, xi_new, phi_u,
                gamma_u2, aux_on, aux_z, aux_var, aux_age, inn, sdiag, s12, nis, dof, K, Fy, Hr, rb,
                track_cross, Pc, pairs):
            b.bank_kernel(x, P, baro_prev, T, dp, dv, g0, g1, q_dh, q_da, phi_g, q_g, has_baro, baro_on, xi_new,
                          phi_u, gamma_u2, aux_on, aux_z, aux_var, aux_age, inn, sdiag, s12, nis, dof, K, Fy, Hr, rb)
            if track_cross:
                cross_kernel(Pc, pairs, T, g0, g1, q_dh, q_da, phi_g, q_g, gamma_u2, dof, K, Fy, Hr, rb)

        b.step_kernel = two
        try:
            return super().step(ep)
        finally:
            b.step_kernel = saved


@pytest.mark.parametrize("seed", [5, 17])
@pytest.mark.parametrize("track_cross", [True, False])
def test_step_kernel_equals_the_two_kernels(seed, track_cross):
    """step_kernel (one compiled call) leaves the same floats as bank_kernel
    then cross_kernel called one after the other, over a long irregular run
    (baro switched off and on per channel, feedback, restarts)."""
    model = Model.from_config(cfg_gm(3.0))
    one, two = ChannelBank(model, track_cross), _TwoCalls(model, track_cross)
    for bank in (one, two):
        bank.start(0, 0.5)
    rng = np.random.default_rng(seed)
    for k, ep in enumerate(random_epochs(seed, 800, measured=True)):
        if k % 50 == 0:
            on = rng.random(len(CHANNELS)) < 0.8
            one.baro_on[:] = on
            two.baro_on[:] = on
        a, b = one.step(ep), two.step(ep)
        for u, v in zip(dataclasses.astuple(a), dataclasses.astuple(b)):
            assert np.array_equal(u, v, equal_nan=True)
        for name in ("x", "P", "Pc", "baro_prev"):
            assert np.array_equal(getattr(one, name), getattr(two, name), equal_nan=True), name
    assert not np.array_equal(one.Pc, np.zeros_like(one.Pc)) or not track_cross


class _Fresh(ChannelBank):
    """A bank that keeps no answer: _g and the decays computed at every call."""

    def _g(self, T, dv_var_m2ps2=0.0):
        return self._g_fresh(T, dv_var_m2ps2)

    def _decay(self, T):
        phi_g, q_g = gnss_gauss_markov(T, self.model)
        return math.exp(-self.model.gamma_bb_per_s * T), phi_g, q_g


@pytest.mark.parametrize("form", ["consistent", "printed"])
def test_kept_noise_terms_are_the_fresh_ones(form):
    """The bank's kept _g and decay answers (asked by the baro and aux
    predictions and the step of one epoch) give the same predictions and
    states as computing them at every call, over epochs whose interval and
    measured IMU noise repeat and change."""
    cfg = cfg_gm(3.0)
    model = dataclasses.replace(Model.from_config(cfg), accel_noise_form=form)
    kept, fresh = ChannelBank(model), _Fresh(model)
    for bank in (kept, fresh):
        bank.start(0, 0.5)
    rng = np.random.default_rng(23)
    for k, ep in enumerate(random_epochs(23, 900, measured=True)):
        if k % 3:  # the same interval and IMU noise as the epoch before: the kept answers serve
            ep = dataclasses.replace(ep, dt_s=0.05, dv_var_m2ps2=0.01 if k % 2 else 0.0)
        for c in range(len(CHANNELS)):
            assert repr(kept.predicted_baro(c, ep)) == repr(fresh.predicted_baro(c, ep))
            for aux in (ep.gnss, ep.rng):
                if aux is not None:
                    assert repr(kept.predicted_aux(c, ep, aux)) == repr(fresh.predicted_aux(c, ep, aux))
        a, b = kept.step(ep), fresh.step(ep)
        for u, v in zip(dataclasses.astuple(a), dataclasses.astuple(b)):
            assert np.array_equal(u, v, equal_nan=True)
        assert np.array_equal(kept.P, fresh.P) and np.array_equal(kept.x, fresh.x)
        if k % 97 == 0:
            kept.baro_on[:] = fresh.baro_on[:] = rng.random(len(CHANNELS)) < 0.7
