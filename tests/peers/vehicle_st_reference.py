"""Reference trajectory of CommonRoad's dynamic single-track (ST) model for the Rust cross-check.

Produces the fixture in common/src/vehicle/single_track.rs (test `agrees_with_commonroad_st`).
Run:
    python3 -m venv /tmp/venv-cr && /tmp/venv-cr/bin/pip install commonroad-vehicle-models==3.0.2
    /tmp/venv-cr/bin/python tests/peers/vehicle_st_reference.py

Model: vehiclemodels.vehicle_dynamics_st with parameters_vehicle2 (BMW 320i), integrated with
classic fixed-step RK4 (dt = 0.01 s, inputs held constant over each step). Inputs are the
CommonRoad ones, u = [steering velocity rad/s, longitudinal acceleration m/s^2]:
    0 <= t < 1 s: u = [ 0.05,  1.0]
    1 <= t < 3 s: u = [-0.05, -2.0]
from x0 = [x, y, delta, v, psi, psi_dot, beta] = [0, 0, 0, 15, 0, 0, 0].
Prints the state every 0.5 s as Rust array literals.
"""
from vehiclemodels.parameters_vehicle2 import parameters_vehicle2
from vehiclemodels.vehicle_dynamics_st import vehicle_dynamics_st

DT = 0.01
STEPS = 300


def inputs(k):
    return [0.05, 1.0] if k < 100 else [-0.05, -2.0]


def rk4(x, u, p, h):
    def f(s):
        return vehicle_dynamics_st(s, u, p)

    k1 = f(x)
    k2 = f([a + 0.5 * h * b for a, b in zip(x, k1)])
    k3 = f([a + 0.5 * h * b for a, b in zip(x, k2)])
    k4 = f([a + h * b for a, b in zip(x, k3)])
    return [a + h / 6.0 * (b + 2.0 * c + 2.0 * d + e) for a, b, c, d, e in zip(x, k1, k2, k3, k4)]


def main():
    p = parameters_vehicle2()
    x = [0.0, 0.0, 0.0, 15.0, 0.0, 0.0, 0.0]
    for k in range(STEPS):
        x = rk4(x, inputs(k), p, DT)
        if (k + 1) % 50 == 0:
            t = (k + 1) * DT
            print(f"({t:.2f}, [{', '.join(repr(v) for v in x)}]),")


if __name__ == "__main__":
    main()
