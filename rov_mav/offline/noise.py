"""The offline loop's sensor-noise generator (compiled): splitmix64 uniforms and ziggurat normals, seeded per run.

splitmix64: Steele, Lea and Flood, "Fast splittable pseudorandom number generators", OOPSLA 2014. Normals by the
ziggurat method (Marsaglia and Tsang, "The ziggurat method for generating random variables", J. Stat. Softw. 5(8),
2000) with 128 layers, in the floating-point form of Doornik ("An improved ziggurat method to generate normal random
samples", 2005): one 64-bit draw gives the layer (its low 7 bits) and a signed uniform (its top 53), and 98.8 % of
normals are that uniform times the layer's width. A normal costs a few ns, against about 15 for the polar method
and 25-30 for np.random.normal in Numba, which made a noisy run cost twice a clean one.
"""

from __future__ import annotations

import math

import numpy as np

from rov_mav.model.kernel import inlined

_GOLDEN_GAMMA = np.uint64(0x9E3779B97F4A7C15)
_MIX1 = np.uint64(0xBF58476D1CE4E5B9)
_MIX2 = np.uint64(0x94D049BB133111EB)
_TO_UNIT = 2.0 ** -53

LAYERS = 128
TAIL_START = 3.442619855899                # R: where the base layer's tail begins (Marsaglia and Tsang, 128 layers)
LAYER_AREA = 9.91256303526217e-3           # V: the area of each layer under exp(-x^2 / 2)


def _layer_edges() -> np.ndarray:
    """x_0 > x_1 = R > ... > x_127 > x_128 = 0: layer i spans [0, x_i] in x, its top at exp(-x_{i+1}^2 / 2)
    (x_0 = V / f(R) is the base layer's equivalent width, its rectangle and the tail together of area V)."""
    x = np.zeros(LAYERS + 1)
    x[0] = LAYER_AREA / math.exp(-0.5 * TAIL_START ** 2)
    x[1] = TAIL_START
    for i in range(2, LAYERS):
        x[i] = math.sqrt(-2.0 * math.log(LAYER_AREA / x[i - 1] + math.exp(-0.5 * x[i - 1] ** 2)))
    return x


_EDGES = _layer_edges()
_INNER = _EDGES[1:] / _EDGES[:-1]   # |u| below this: the sample lies under the layer above, accepted at once


@inlined
def _next(rng):
    """(next state, 64 mixed bits) of the splitmix64 state rng (uint64)."""
    rng = rng + _GOLDEN_GAMMA
    z = (rng ^ (rng >> np.uint64(30))) * _MIX1
    z = (z ^ (z >> np.uint64(27))) * _MIX2
    return rng, z ^ (z >> np.uint64(31))


@inlined
def uniform(rng):
    """(next state, a uniform double in [0, 1))."""
    rng, z = _next(rng)
    return rng, (z >> np.uint64(11)) * _TO_UNIT


@inlined
def _tail(rng, negative):
    """A normal beyond R (Marsaglia, 1964): x = -ln(U1) / R, y = -ln(U2), accepted when 2 y > x^2."""
    while True:
        rng, u1 = uniform(rng)
        rng, u2 = uniform(rng)
        x = -math.log(1.0 - u1) / TAIL_START
        if -2.0 * math.log(1.0 - u2) > x * x:
            return rng, -(TAIL_START + x) if negative else TAIL_START + x


@inlined
def normal(rng):
    """(next state, a standard normal)."""
    while True:
        rng, z = _next(rng)
        layer = np.int64(z & np.uint64(LAYERS - 1))
        u = 2.0 * ((z >> np.uint64(11)) * _TO_UNIT) - 1.0
        if abs(u) < _INNER[layer]:
            return rng, u * _EDGES[layer]
        if layer == 0:
            return _tail(rng, u < 0.0)
        x = u * _EDGES[layer]
        top = math.exp(-0.5 * (_EDGES[layer + 1] ** 2 - x * x))
        bottom = math.exp(-0.5 * (_EDGES[layer] ** 2 - x * x))
        rng, v = uniform(rng)
        if bottom + v * (top - bottom) < 1.0:
            return rng, x
