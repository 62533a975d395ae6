"""Estimation for a powered muscle: what it senses of itself, and the loop closed on it.

- :mod:`tcamlab.estimation.observer`: the causal EKF of the self-sensing kind (temperature,
  extension, velocity, load and a thermal correction as states; R = V / I and, where logged,
  the load as measurements; a load-jump detector where it is not), its resistance table and its noise settings;
- :mod:`tcamlab.estimation.observer_kernel`: the filter's compiled step and the muscle's
  equilibrium (numba);
- :mod:`tcamlab.estimation.observability`: which states voltage and current can tell apart
  over a protocol (the linearised observability Gramian, its rank and condition number);
- :mod:`tcamlab.estimation.control`: the closed-loop study on the virtual rig
  (``tcamlab closed-loop``): the controller, the plant and their scores;
- :mod:`tcamlab.estimation.control_kernel`: the compiled loop of that study.

The :mod:`tcamlab.kinds.selfsensing` kind calls the observer as its ``"ekf"`` estimator.
"""
