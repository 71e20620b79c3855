"""The INS+USBL Kalman filter (Du et al. 2018, eqs. 8-17), error-state and closed-loop.

State (eq. 8), 15 errors of the strapdown solution, each "estimate minus truth": position (north, east, down;
m, on the local plane, where the paper writes latitude, longitude and height), velocity (north, east, down),
attitude (the small rotation ``phi`` with ``C_estimate = (I - [phi x]) C_true``, rad), gyro drifts (rad/s) and
accelerometer biases (m/s^2) in the body frame; and a 16th, the fractional error ``b`` of the path-mean sound speed
the fixes are computed with (:class:`SoundSpeedError`: first-order Gauss-Markov, its variance growing with the
cast's age). The error dynamics (eq. 9) on the Earth-fixed local plane, with
``Omega`` the Earth's rate there:

    d(dp)/dt = dv
    d(dv)/dt = [f_n x] phi - 2 [Omega x] dv - C db_a + C w_a     (f_n: the specific force in NED)
    d(phi)/dt = -[Omega x] phi + C db_g - C w_g
    d(db_g)/dt = w_bg,  d(db_a)/dt = w_ba                        (random walks)

discretised as ``Phi = I + F dt + (F dt)^2 / 2`` and ``Q_d = Q dt`` at every IMU sample (eqs. 12, 13, 16).
A USBL fix gives the measurement of eq. 11, INS minus USBL position, ``H = [I 0 0 0 0 J]`` (``J`` the fix's
displacement per unit of ``b``, ``UsblFix.sound_speed_jacobian_m``), with the fix's own
covariance (3 x 3: its horizontal error and its depth are correlated) as ``R``; eqs. 14, 15 and 17 (in Joseph
form) update. Before an update the innovation's normalised square ``nu' S^-1 nu`` is compared with the
chi-square quantile of 3 degrees of freedom at ``gate_probability``; a fix beyond it is rejected and the INS
carries on (as it does through dropouts), its depth still held by the towfish's pressure depth (a
one-dimensional update gated at 1 dof). After an update the errors
are fed back into the strapdown solution, the bias estimates and the sound speed's, and reset to zero.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.stats import chi2

from .fix import UsblFix
from .frames import rotation_from_vector, skew
from .ins import EarthModel, ImuSamples, NavState, strapdown_step

__all__ = ["ImuNoise", "InsUsblFilter", "FusionResult", "fuse"]

POSITION, VELOCITY, ATTITUDE, GYRO, ACCEL = (slice(3 * k, 3 * k + 3) for k in range(5))
#: The 16th state: the processing's error in the path-mean sound speed, as a fraction (its speed over the truth's, less 1).
SOUND = 15
STATES = 16


@dataclass(frozen=True)
class ImuNoise:
    """The IMU's noise as the filter models it (one-sigma, continuous-time densities).

    Parameters
    ----------
    velocity_random_walk : float
        Accelerometer white noise, m/s/sqrt(s).
    angle_random_walk : float
        Gyro white noise, rad/sqrt(s).
    gyro_bias_walk : float
        Gyro drift random walk, rad/s/sqrt(s).
    accel_bias_walk : float
        Accelerometer bias random walk, m/s^2/sqrt(s).
    """

    velocity_random_walk: float = 5e-4
    angle_random_walk: float = 2e-5
    gyro_bias_walk: float = 1e-8
    accel_bias_walk: float = 1e-6

    def density(self) -> np.ndarray:
        """Diagonal of the continuous process noise for the 16 states (the sound speed's is :class:`SoundSpeedError`'s)."""
        return np.concatenate([np.zeros(3), np.full(3, self.velocity_random_walk**2), np.full(3, self.angle_random_walk**2),
                               np.full(3, self.gyro_bias_walk**2), np.full(3, self.accel_bias_walk**2), [0.0]])


@dataclass(frozen=True)
class SoundSpeedError:
    """The error of the path-mean sound speed the fixes are computed with, as the filter models it: a first-order
    Gauss-Markov fraction whose variance at time ``t`` after the start is
    ``((sigma_m_s)^2 + (drift_m_s_per_h (age_h + t / 3600))^2) / speed_m_s^2`` (the cast's own error and internal waves,
    and a surface layer drifting since the cast, seen through its share of the path), correlated over ``correlation_s``.
    """

    sigma_m_s: float = 0.0
    drift_m_s_per_h: float = 0.0
    age_h: float = 0.0
    correlation_s: float = 600.0
    speed_m_s: float = 1500.0

    def variance(self, time_s: float) -> float:
        drift = self.drift_m_s_per_h * (self.age_h + time_s / 3600.0)
        return (self.sigma_m_s**2 + drift**2) / self.speed_m_s**2


@dataclass
class InsUsblFilter:
    """Strapdown INS with the 16-state error Kalman filter (15 of the INS, one of the sound speed).

    Parameters
    ----------
    state : NavState
        The INS solution at the start.
    covariance : numpy.ndarray
        16 x 16 covariance of the starting errors (15 x 15: the sound speed's starts at its model's variance, uncorrelated).
    noise : ImuNoise
        The IMU's noise model.
    earth : EarthModel
        Gravity and the Earth's rotation on the local plane.
    gate_probability : float
        Fixes whose innovation lies beyond this chi-square quantile (3 dof) are rejected.
    transponder_lever_arm_m : numpy.ndarray
        From the INS (and its pressure sensor) to the USBL transponder, body frame (forward, starboard, down), m.
    """

    state: NavState
    covariance: np.ndarray
    noise: ImuNoise
    earth: EarthModel
    gate_probability: float = 0.999
    transponder_lever_arm_m: np.ndarray = field(default_factory=lambda: np.zeros(3))
    sound_speed: SoundSpeedError = field(default_factory=SoundSpeedError)
    gyro_bias: np.ndarray = field(default_factory=lambda: np.zeros(3))
    accel_bias: np.ndarray = field(default_factory=lambda: np.zeros(3))
    sound_speed_fraction: float = 0.0
    elapsed_s: float = 0.0

    def __post_init__(self) -> None:
        if self.covariance.shape == (15, 15):  # no sound-speed state given: it starts at its own prior
            covariance = np.zeros((STATES, STATES))
            covariance[:15, :15] = self.covariance
            covariance[SOUND, SOUND] = self.sound_speed.variance(0.0)
            self.covariance = covariance
        if self.covariance.shape != (STATES, STATES):
            raise ValueError(f"the filter's covariance must be {STATES} x {STATES} (or 15 x 15 without the sound speed's), got {self.covariance.shape}")
        self.transponder_lever_arm_m = np.asarray(self.transponder_lever_arm_m, dtype=float)
        if not 0.0 < self.gate_probability < 1.0:
            raise ValueError(f"gate_probability must lie in (0, 1), got {self.gate_probability}")
        self._gate = float(chi2.ppf(self.gate_probability, 3))
        self._depth_gate = float(chi2.ppf(self.gate_probability, 1))
        self._density = self.noise.density()

    @property
    def gate(self) -> float:
        """The innovation's chi-square threshold."""
        return self._gate

    def predict(self, specific_force: np.ndarray, angular_rate: np.ndarray, dt: float) -> None:
        """One IMU sample: the strapdown step on bias-corrected rates, the covariance by eq. 16."""
        force = specific_force - self.accel_bias
        rate = angular_rate - self.gyro_bias
        attitude = self.state.attitude
        self.state = strapdown_step(self.state, force, rate, dt, self.earth)
        earth = skew(self.earth.rate_ned)
        dynamics = np.zeros((STATES, STATES))
        dynamics[POSITION, VELOCITY] = np.eye(3)
        dynamics[VELOCITY, VELOCITY] = -2.0 * earth
        dynamics[VELOCITY, ATTITUDE] = skew(attitude @ force)
        dynamics[VELOCITY, ACCEL] = -attitude
        dynamics[ATTITUDE, ATTITUDE] = -earth
        dynamics[ATTITUDE, GYRO] = attitude
        step = dynamics * dt
        transition = np.eye(STATES) + step + step @ step / 2.0
        decay = np.exp(-dt / self.sound_speed.correlation_s)
        transition[SOUND, SOUND] = decay
        noise = self._density * dt
        # The Gauss-Markov fraction keeps the variance the model gives at every time (growing as the cast ages).
        noise[SOUND] = max(self.sound_speed.variance(self.elapsed_s + dt) - decay**2 * self.sound_speed.variance(self.elapsed_s), 0.0)
        self.covariance = transition @ self.covariance @ transition.T + np.diag(noise)
        self.sound_speed_fraction *= decay
        self.elapsed_s += dt

    def update(self, fix: UsblFix) -> tuple[bool, float]:
        """Eqs. 14, 15, 17 with a USBL fix, after the chi-square gate; returns (accepted, normalised innovation squared).

        The fix is the transponder's position, ``transponder_lever_arm_m`` from the INS in the body frame: the
        predicted one is ``p + C l``, whose error ``dp + [(C l) x] phi`` gives ``H`` its attitude columns.
        """
        lever = self.state.attitude @ self.transponder_lever_arm_m
        measured = np.array([fix.north_m, fix.east_m, fix.depth_m])
        # Eq. 11, INS minus USBL (the predicted error state is zero), the fix moved by the sound-speed error estimated so far.
        innovation = self.state.position + lever + fix.sound_speed_jacobian_m * self.sound_speed_fraction - measured
        observation = np.zeros((3, STATES))
        observation[:, POSITION] = np.eye(3)
        observation[:, ATTITUDE] = skew(lever)
        observation[:, SOUND] = fix.sound_speed_jacobian_m
        noise = fix.covariance_ned
        projected = observation @ self.covariance
        innovation_cov = projected @ observation.T + noise
        nis = float(innovation @ np.linalg.solve(innovation_cov, innovation))
        if nis > self._gate:
            return False, nis
        gain = np.linalg.solve(innovation_cov, projected).T  # eq. 15 (S symmetric)
        error = gain @ innovation  # eq. 14
        keep = np.eye(STATES) - gain @ observation
        self.covariance = keep @ self.covariance @ keep.T + gain @ noise @ gain.T  # eq. 17, Joseph form
        self._feed_back(error)
        return True, nis

    def update_depth(self, depth_m: float, variance_m2: float) -> tuple[bool, float]:
        """A pressure depth alone (between fixes, or with a rejected one): the same update on the down axis, gated at
        the chi-square quantile of 1 dof."""
        innovation = self.state.position[2] - depth_m
        innovation_var = self.covariance[2, 2] + variance_m2
        nis = innovation**2 / innovation_var
        if nis > self._depth_gate:
            return False, float(nis)
        gain = self.covariance[:, 2] / innovation_var
        keep = np.eye(STATES)
        keep[:, 2] -= gain
        self.covariance = keep @ self.covariance @ keep.T + variance_m2 * np.outer(gain, gain)
        self._feed_back(gain * innovation)
        return True, float(nis)

    def _feed_back(self, error: np.ndarray) -> None:
        self.state = NavState(self.state.position - error[POSITION], self.state.velocity - error[VELOCITY],
                              rotation_from_vector(error[ATTITUDE]) @ self.state.attitude)
        self.gyro_bias = self.gyro_bias - error[GYRO]
        self.accel_bias = self.accel_bias - error[ACCEL]
        self.sound_speed_fraction -= float(error[SOUND])

    def position_covariance(self) -> np.ndarray:
        return self.covariance[POSITION, POSITION].copy()


@dataclass(frozen=True)
class FusionResult:
    """The fused track at every USBL epoch: times, positions (n x 3, NED), their covariances (n x 3 x 3),
    velocities (n x 3), attitudes (n x 3 x 3), and per epoch whether a fix came, was accepted, and its NIS
    (NaN without a fix)."""

    time_s: np.ndarray
    position: np.ndarray
    covariance: np.ndarray
    velocity: np.ndarray
    attitude: np.ndarray
    had_fix: np.ndarray
    accepted: np.ndarray
    nis: np.ndarray
    gate: float


def fuse(imu: ImuSamples, epochs_s: np.ndarray, fixes: list[UsblFix | None], filt: InsUsblFilter, *,
         depths_m: np.ndarray | None = None, depth_variance_m2: float | None = None) -> FusionResult:
    """Run the filter over the IMU samples, updating at each epoch's fix (``None``: a dropout).

    The filter's state must be at ``imu.time_s[0]``; an epoch between two samples is reached by a partial step
    with the later sample's rates. Epochs must increase and lie within the IMU's time span. With ``depths_m`` (the
    towfish's pressure depth at every epoch), an epoch without an accepted fix still updates the depth.
    """
    epochs = np.asarray(epochs_s, dtype=float)
    if len(fixes) != epochs.size:
        raise ValueError(f"fuse: {epochs.size} epochs but {len(fixes)} fixes")
    if epochs.size and (epochs[0] < imu.time_s[0] or epochs[-1] > imu.time_s[-1] or np.any(np.diff(epochs) <= 0.0)):
        raise ValueError(f"fuse: the USBL epochs ({epochs[0]:.2f} to {epochs[-1]:.2f} s) must increase and lie within the IMU's "
                         f"{imu.time_s[0]:.2f} to {imu.time_s[-1]:.2f} s")
    n = epochs.size
    position, velocity = np.empty((n, 3)), np.empty((n, 3))
    covariance, attitude = np.empty((n, 3, 3)), np.empty((n, 3, 3))
    had_fix, accepted, nis = np.zeros(n, bool), np.zeros(n, bool), np.full(n, np.nan)
    now, sample = imu.time_s[0], 1
    for e, epoch in enumerate(epochs):
        while sample < imu.time_s.size and imu.time_s[sample] <= epoch:
            filt.predict(imu.specific_force[sample], imu.angular_rate[sample], imu.time_s[sample] - now)
            now, sample = imu.time_s[sample], sample + 1
        if epoch > now:
            filt.predict(imu.specific_force[sample], imu.angular_rate[sample], epoch - now)
            now = epoch
        if fixes[e] is not None:
            had_fix[e] = True
            accepted[e], nis[e] = filt.update(fixes[e])
        if not accepted[e] and depths_m is not None and np.isfinite(depths_m[e]):
            filt.update_depth(float(depths_m[e]), depth_variance_m2)
        position[e], velocity[e], attitude[e] = filt.state.position, filt.state.velocity, filt.state.attitude
        covariance[e] = filt.position_covariance()
    return FusionResult(epochs, position, covariance, velocity, attitude, had_fix, accepted, nis, filt.gate)
