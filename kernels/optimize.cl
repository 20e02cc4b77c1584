// optimize.cl — first-order optimiser steps on the device (lib/reconstruct/optimize.cpp): Adam and SGD with
// momentum, each followed by the projection onto the box [lower, upper] (density ≥ 0, colours in
// [0, 1], …). One work-item per parameter.
#include "config.cl"

// Adam (Kingma & Ba 2015): m ← β₁m + (1 − β₁)g, v ← β₂v + (1 − β₂)g²,
// x ← x − lr·(m / c₁) / (sqrt(v / c₂) + ε) with the bias corrections c₁ = 1 − β₁ᵗ, c₂ = 1 − β₂ᵗ.
__kernel void adam_step(const int n, const real lr, const real beta1, const real beta2,
                        const real epsilon, const real c1, const real c2, const real lower,
                        const real upper, __global real* restrict x,
                        __global const real* restrict g, __global real* restrict m,
                        __global real* restrict v) {
  const int i = get_global_id(0);
  if (i >= n) return;
  const real gi = g[i];
  const real mi = beta1 * m[i] + ((real)1 - beta1) * gi;
  const real vi = beta2 * v[i] + ((real)1 - beta2) * gi * gi;
  m[i] = mi;
  v[i] = vi;
  const real xi = x[i] - lr * (mi / c1) / (sqrt(vi / c2) + epsilon);
  x[i] = fmin(fmax(xi, lower), upper);
}

// SGD with (heavy-ball) momentum: u ← μu + g, x ← x − lr·u.
__kernel void sgd_step(const int n, const real lr, const real momentum, const real lower,
                       const real upper, __global real* restrict x, __global const real* restrict g,
                       __global real* restrict u) {
  const int i = get_global_id(0);
  if (i >= n) return;
  const real ui = momentum * u[i] + g[i];
  u[i] = ui;
  x[i] = fmin(fmax(x[i] - lr * ui, lower), upper);
}
