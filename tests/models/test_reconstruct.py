import numpy as np
import pytest

from scioc.models.assistant import design_assistant
from scioc.models.plant import discretize, propagate
from scioc.models.reconstruct import DEFAULT_RESOLUTION, reconstruct
from scioc.models.reference import reference_trajectory
from scioc.models.simulate import simulate_run


@pytest.fixture(scope="module")
def run():
    plant, asst = discretize(0.01), design_assistant()
    ref = reference_trajectory(20.0).angle
    return simulate_run([400.0, 0.0, 20.0], "SC", ref, plant, asst, np.random.default_rng(7))


def test_reconstruction_is_consistent_with_the_plant(run):
    plant = discretize(0.01)
    rec = reconstruct(run.angle, run.u_A, plant)
    x = propagate(plant, [rec.angle[0], rec.velocity[0]], rec.u_H[:-1] + run.u_A[:-1])
    np.testing.assert_allclose(x[:, 0], rec.angle, atol=1e-12)
    np.testing.assert_allclose(x[:, 1], rec.velocity, atol=1e-10)


def test_reconstruction_recovers_velocity_and_most_of_the_torque(run):
    rec = reconstruct(run.angle, run.u_A, discretize(0.01))
    assert np.sqrt(np.mean((rec.velocity - run.true_velocity) ** 2)) < 0.02  # rad/s; velocity RMS ~0.2
    corr = np.corrcoef(rec.u_H[:-1], run.u_H[:-1])[0, 1]
    assert corr > 0.8
    # The white torque SD it chose is near the truth, 1/sqrt(2 S) with S ≈ R = 20: about 0.16 N·m.
    assert 0.1 < rec.sigma_eps < 0.22
    # What stays below the encoder's resolution is lost: the reconstruction is smoother.
    assert np.std(rec.u_H[:-1]) < np.std(run.u_H[:-1])


def test_a_finer_encoder_recovers_more(run):
    plant = discretize(0.01)
    coarse = reconstruct(run.angle, run.u_A, plant)
    fine = reconstruct(run.true_angle, run.u_A, plant, resolution=DEFAULT_RESOLUTION / 100)
    err = lambda r: np.sqrt(np.mean((r.u_H[:-1] - run.u_H[:-1]) ** 2))  # noqa: E731
    assert err(fine) < 0.5 * err(coarse)


def test_naive_inversion_amplifies_quantization(run):
    # Why we do not invert step by step: one increment is worth ~0.13 N·m in one step.
    plant = discretize(0.01)
    A, b = plant.A, plant.b
    phi = run.angle
    # Exact inversion given angle only: velocity from the angle row, torque from it.
    v = np.empty_like(phi)
    v[0] = run.true_velocity[0]
    u = np.empty(phi.shape[0] - 1)
    for k in range(phi.shape[0] - 1):
        tot = (phi[k + 1] - A[0, 0] * phi[k] - A[0, 1] * v[k]) / b[0]
        u[k] = tot - run.u_A[k]
        v[k + 1] = A[1, 0] * phi[k] + A[1, 1] * v[k] + b[1] * tot
    naive = np.sqrt(np.mean((u[:500] - run.u_H[:500]) ** 2))
    rec = reconstruct(run.angle, run.u_A, plant)
    # Measured here: about 8.5 times the smoother's error (0.71 vs 0.083 N·m).
    assert naive > 5 * np.sqrt(np.mean((rec.u_H[:500] - run.u_H[:500]) ** 2))


def test_bad_inputs_are_rejected():
    with pytest.raises(ValueError, match="at least 3"):
        reconstruct(np.zeros(2), np.zeros(2), discretize(0.01))
    with pytest.raises(ValueError, match="resolution"):
        reconstruct(np.zeros(10), np.zeros(10), discretize(0.01), resolution=0.0)
