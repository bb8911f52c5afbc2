"""A Kalman filter on the delay-extended model, in NumPy, as a filterpy user would write it:
the state is [x[k]; x[k-1]; ...; x[k-dbar]], a sample taken at period s that arrives at period k
measures block k - s, and every sample that arrived in a period is used in one batch update.

It is the filter of ncosim's built-in kind `kalman_extended`, written independently in ~40 lines:
python/tests/test_estimator.py checks that both give the same per-run MSE on the same campaign.
"""
import numpy as np

import ncosim


@ncosim.register("numpy_kf", help="Kalman filter on the delay-extended model, in NumPy")
class DelayKF(ncosim.Estimator):
    def __init__(self, model, params):
        super().__init__(model, params)
        self.d = int(params.get("max_delay", 0))
        if self.d < 0:
            raise ValueError(f"max_delay: expected an integer >= 0, got {self.d}")
        n, nb = model.n, model.n * (self.d + 1)
        self.n = n
        self.F = np.zeros((nb, nb))  # x[k] = A x[k-1]; the older blocks shift down one place
        self.F[:n, :n] = model.A
        self.F[n:, :-n] = np.eye(n * self.d)
        self.Q = np.zeros((nb, nb))
        self.Q[:n, :n] = model.Q
        self.x = np.tile(model.x0, self.d + 1)
        self.P = np.zeros((nb, nb))
        self.seen = set()  # (sensor, stamp) of the samples used: a sample counts once
        self.H, self.z, self.R = [], [], []
        self.flops = 2 * nb**3  # the order of one update's cost

    def on_packet(self, packet, k):
        s = self.model.sensors[packet.sensor]
        ny, used = s.C.shape[0], 0
        for i, stamp in enumerate(packet.stamps):
            age = k - stamp
            if age > self.d or (packet.sensor, stamp) in self.seen:
                continue
            self.seen.add((packet.sensor, stamp))
            H = np.zeros((ny, self.x.size))
            H[:, age * self.n:(age + 1) * self.n] = s.C
            self.H.append(H)
            self.z.append(packet.values[i * ny:(i + 1) * ny])
            self.R.append(s.R)
            used += 1
        return used

    def on_period(self, k, u, drive):
        if k > 0:  # predict
            self.x = self.F @ self.x
            self.x[:self.n] += drive
            self.P = self.F @ self.P @ self.F.T + self.Q
        if self.H:  # update with every sample that arrived
            H, z = np.vstack(self.H), np.concatenate(self.z)
            R = np.zeros((len(z), len(z)))
            r = 0
            for Ri in self.R:
                R[r:r + len(Ri), r:r + len(Ri)] = Ri
                r += len(Ri)
            S = H @ self.P @ H.T + R
            K = np.linalg.solve(S, H @ self.P).T  # P H' S^-1 (S and P symmetric)
            self.x = self.x + K @ (z - H @ self.x)
            self.P = self.P - K @ H @ self.P
            self.P = 0.5 * (self.P + self.P.T)
            self.H, self.z, self.R = [], [], []
        if k % 64 == 0:  # forget samples too old to arrive again in time
            self.seen = {(i, s) for i, s in self.seen if k - s <= self.d}

    def state(self):
        return self.x[:self.n]

    def covariance(self):
        return self.P[:self.n, :self.n]
