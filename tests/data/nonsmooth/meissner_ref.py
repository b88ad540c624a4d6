import numpy as np
from scipy.optimize import brentq
def M(k, tau):
    if k > 0:
        w = np.sqrt(k); return np.array([[np.cos(w*tau), np.sin(w*tau)/w], [-w*np.sin(w*tau), np.cos(w*tau)]])
    if k < 0:
        w = np.sqrt(-k); return np.array([[np.cosh(w*tau), np.sinh(w*tau)/w], [w*np.sinh(w*tau), np.cosh(w*tau)]])
    return np.array([[1.0, tau], [0.0, 1.0]])
def trace(delta, eps):
    # sign(cos t): + on [0,pi/2), - on (pi/2,3pi/2), + on (3pi/2,2pi]
    m = M(delta+eps, np.pi/2) @ M(delta-eps, np.pi) @ M(delta+eps, np.pi/2)
    return np.trace(m)
def mu(delta, eps):
    m = M(delta+eps, np.pi/2) @ M(delta-eps, np.pi) @ M(delta+eps, np.pi/2)
    return max(abs(np.linalg.eigvals(m)))
def boundaries(eps, lo, hi, n=20001):
    d = np.linspace(lo, hi, n)
    out = []
    for s in (2.0, -2.0):
        g = np.array([trace(x, eps) - s for x in d])
        for i in np.nonzero(np.sign(g[:-1]) != np.sign(g[1:]))[0]:
            out.append(brentq(lambda x: trace(x, eps) - s, d[i], d[i+1], xtol=1e-15, rtol=1e-15))
    return sorted(out)
if __name__ == "__main__":
    import sys
    eps = float(sys.argv[1]) if len(sys.argv) > 1 else 0.3
    for b in boundaries(eps, -0.5, 3.0):
        print(repr(b), trace(b, eps))
