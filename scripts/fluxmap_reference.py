#!/usr/bin/env python3
# Usage: python3 scripts/fluxmap_reference.py [MAP.npz]  (needs numpy; not part of CI)
# The rms flux residual of motulator's published PM-SyRM saturation model (its Baldor example's
# parameters) on the measured map: invert i(psi) at each grid current by Newton (numeric Jacobian).
import numpy as np
import sys
d = np.load(sys.argv[1] if len(sys.argv) > 1 else '../shared/data/real/baldor_400rpm_map.npz')
I = d['i_s_dq'].ravel(); P = d['psi_s_dq'].ravel()
a_d0,a_dd,S,a_q0,a_qq,T,a_dq,U,V,a_b,a_bp,k_q,psi_n,W = 3.96,28.5,4,5.89,2.67,6,41.5,1,1,81.75,1,0.1,0.804,2
def i_s(p):
    pd,pq = p.real,p.imag
    G_d = a_d0 + a_dd*abs(pd)**S + a_dq/(V+2)*abs(pd)**U*abs(pq)**(V+2)
    G_q = a_q0 + a_qq*abs(pq)**T + a_dq/(U+2)*abs(pd)**(U+2)*abs(pq)**V
    pb = pd - psi_n
    pbs = np.sqrt(pb**2 + k_q*pq**2)
    G_b = a_b*pbs**W/(1+a_bp*pbs**W)
    return G_d*pd + G_b*pb + 1j*(G_q + k_q*G_b)*pq
res = []
for i, pm in zip(I, P):
    p = pm
    for _ in range(100):
        r = i_s(p) - i
        e = 1e-7
        j1 = (i_s(p+e)-i_s(p-e))/(2*e); j2 = (i_s(p+1j*e)-i_s(p-1j*e))/(2*e)
        J = np.array([[j1.real, j2.real],[j1.imag, j2.imag]])
        dx = np.linalg.solve(J, [r.real, r.imag])
        p = p - (dx[0] + 1j*dx[1])
        if abs(dx[0])+abs(dx[1]) < 1e-13: break
    res.append(p - pm)
res = np.array(res)
rng = max(np.ptp(P.real), np.ptp(P.imag))
rms = np.sqrt(np.mean(abs(res)**2)/2)
print(f"motulator PM-SyRM model: rms flux residual {rms:.3e} V s = {100*rms/rng:.3f} % of range {rng:.4f}; max {abs(res).max():.3e}")
print("psi at i=0:", P[np.argmin(abs(I))])
