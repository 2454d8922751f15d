"""The batched world's and the agent loop's inner loops, compiled with numba: the same numbers, faster.

Each function stands for numpy code named in its docstring and computes every value with the same
floating-point operations in the same order: ``sqrt``, ``floor``, ``degrees`` and ``radians`` are the same
IEEE operations in numba as in numpy, numba does not contract ``a*b + c`` into FMA, and comparisons and
integer bit operations are exact.  Sine, cosine and arctangent are :mod:`coevo.exactmath`'s, compiled from
its scalar forms (numpy's and libm's own differ between processors).  ``tests/test_exact_curves.py`` runs
everything both ways against the same recorded numbers.

What a kernel saves is mostly numpy's fixed cost per call (~1-10 µs, whatever the batch): a step of the
agent loop was ~90 numpy calls, ~90 µs for a 12-lane batch.

Importing this module imports numba (~0.35 s, ~90 MB): :mod:`.world` imports it only when a batch is big
enough to pay for that (``world.COMPILED_MIN_LANES``).  Compiled code is cached in ``__pycache__``.
"""

from __future__ import annotations

import numba
import numpy as np

from coevo import exactmath

__all__ = ["atan2_into", "move", "assign_probes", "contact_codes", "events", "active_lanes", "decide_lanes", "tally",
           "experiences"]

_jit = numba.njit(cache=True, nogil=True)
_inline = numba.njit(cache=True, nogil=True, inline="always")  # helpers: numba inlines them into their callers
_sincos = _inline(exactmath.sincos_scalar)
_atan2 = _inline(exactmath.atan2_scalar)
_ONE = np.uint64(1)
_ALL = np.uint64(0xFFFF_FFFF_FFFF_FFFF)
_TWO_PI = 2 * np.pi
_INV_TWO_PI = 0.5 / np.pi

# A sensor's code is the index of its name in world.SENSOR_NAMES (world.sensor_tables); the geometry (``geom``,
# BatchWorld._geom): arena, dock x0, dock x1, dock depth, robot radius, Target radius, dock point x, y.


@_jit
def atan2_into(y, x, out):  # pragma: no cover - compiled by numba
    """``out[:] = exactmath.atan2(y, x)``, without numpy's ~30 calls."""
    for i in range(out.shape[0]):
        out[i] = _atan2(y[i], x[i])


# ----------------------------------------------------------------- sensing (BatchWorld._observe + Schema.discretise)
@_inline
def _wrap(a):  # pragma: no cover - compiled by numba
    """world.wrap_deg of one angle."""
    return a - 360.0 * np.floor(a * (1.0 / 360.0))


@_inline
def _range_bearing(code, x, y, h, t_dist, t_dir, q_dir, arena, x0, x1, depth, r, tr):  # pragma: no cover
    """The ``range`` (code 0) or ``bearing`` (1) of the nearest object: ``_observe``'s gaps, first of equals winning."""
    qx = min(max(x, x0), x1)
    qy = min(y, depth)
    gx = x - qx
    gy = y - qy
    g4 = np.sqrt(gx * gx + gy * gy) - r
    g0 = x - r
    g1 = (arena - x) - r
    g2 = y - r
    g3 = (arena - y) - r
    g5 = (t_dist - tr) - r
    nearest = min(min(min(min(min(g0, g1), g2), g3), g4), g5)
    if code == 0:
        return nearest if nearest >= 0.0 else 0.0
    if g0 == nearest:
        od = 180.0
    elif g1 == nearest:
        od = 0.0
    elif g2 == nearest:
        od = -90.0
    elif g3 == nearest:
        od = 90.0
    elif g4 == nearest:
        od = q_dir
    else:
        od = t_dir
    return _wrap(od - h)


@_inline
def _sense_lane(sensors, x, y, rh, tx, ty, th, fuel, t_dir, q_dir, d_dir, geom, out):  # pragma: no cover
    """The bins of every sensor of one lane into ``out`` (S,): raw values as ``_observe`` computes them
    (``t_dir``, ``q_dir``, ``d_dir``: arctangents in degrees), binned as ``Sensor.discretise`` does."""
    codes, inv_width, nbins, circular, origin = sensors
    arena, x0, x1, depth, r, tr, dock_x, dock_y = geom[0], geom[1], geom[2], geom[3], geom[4], geom[5], geom[6], geom[7]
    h = np.degrees(rh)
    dx = tx - x
    dy = ty - y
    t_dist = np.sqrt(dx * dx + dy * dy)
    for j in range(codes.shape[0]):
        code = codes[j]
        if code <= 1:  # range, bearing
            v = _range_bearing(code, x, y, h, t_dist, t_dir, q_dir, arena, x0, x1, depth, r, tr)
        elif code == 2:  # heading
            v = _wrap(np.degrees(th) - t_dir)
        elif code == 3:  # target_range
            v = t_dist
        elif code == 4:  # target_bearing
            v = _wrap(t_dir - h)
        elif code == 5:  # dock_range
            ddx = dock_x - x
            ddy = dock_y - y
            v = np.sqrt(ddx * ddx + ddy * ddy)
        elif code == 6:  # dock_bearing
            v = _wrap(d_dir - h)
        elif code == 7:  # dock_orientation
            v = _wrap(h - -90.0)
        elif code == 8:  # fuel
            v = 100.0 * min(max(fuel, 0.0), 1.0)
        elif code == 9:  # dock_axis (dock_frame.observe)
            v = y - (dock_y + r)
        else:  # dock_offset
            v = x - dock_x
        # Sensor.discretise
        if origin[j] != 0.0:
            v = v - origin[j]
        if circular[j]:
            k = int((v - 360.0 * np.floor(v * (1.0 / 360.0))) * inv_width[j])
            if k >= nbins[j]:
                k -= nbins[j]
        else:
            k = int(min(max(v * inv_width[j], 0.0), nbins[j] - 1.0))
        out[j] = k


# ----------------------------------------------------------------- stepping (BatchWorld.step)
@_jit
def move(active, speed_in, turn_in, speed, turn, dt, state, walk, noise, idx, blocked, bdy, bdx, reach,
         probing):  # pragma: no cover - compiled by numba
    """The robots' kinematic integration and the Targets' random walk of the ``active`` lanes, then
    :func:`_reach` of the robots where they now are.

    Stores the commands (``speed``, ``turn``: those given where active, else 0) and the active lanes in
    ``idx``; a Target that must turn away from a wall or the dock is left for :func:`events` with its lane
    in ``blocked`` and the arguments of its arctan2 (towards the arena's centre) in ``bdy``, ``bdx``.
    ``state``: rh, gx, gy, ga, ox, oy, rx, ry, th, tx, ty.  Returns (active lanes, blocked Targets, and
    :func:`_reach`'s three).
    """
    rh, gx, gy, ga, ox, oy, rx, ry, th, tx, ty = state
    avoid, lo, hi, dock_y, half, dock_w = walk[0], walk[1], walk[2], walk[3], walk[4], walk[5]
    t_step, cx, cy = walk[6], walk[7], walk[8]
    m = 0
    nb = 0
    for i in range(active.shape[0]):
        if not active[i]:
            speed[i] = 0.0
            turn[i] = 0.0
            continue
        sp = speed_in[i]
        tu = turn_in[i]
        speed[i] = sp
        turn[i] = tu
        idx[m] = i
        m += 1
        sin_h, cos_h = _sincos(rh[i])
        x = gx[i] + sp * cos_h * dt
        y = gy[i] + sp * sin_h * dt
        a = ga[i] + np.radians(tu) * dt
        gx[i] = x
        gy[i] = y
        ga[i] = a
        rx[i] = x - ox[i]
        ry[i] = y - oy[i]
        rh[i] = a - _TWO_PI * np.floor((a + np.pi) * _INV_TWO_PI)
        t = th[i] + np.radians(noise[i])
        t = t - _TWO_PI * np.floor((t + np.pi) * _INV_TWO_PI)
        s, c = _sincos(t)
        ax = tx[i] + avoid * c
        ay = ty[i] + avoid * s
        if ax < lo or ax > hi or ay < lo or ay > hi or (ay < dock_y and abs(ax - half) < dock_w):
            blocked[nb] = i
            bdy[nb] = cy - ty[i]
            bdx[nb] = cx - tx[i]
            nb += 1
        else:
            tx[i] = tx[i] + t_step * c
            ty[i] = ty[i] + t_step * s
            th[i] = t
    stepping, need, free = _reach(gx, gy, reach, probing)
    return m, nb, stepping, need, free


@_inline
def _reach(gx, gy, reach, probing):  # pragma: no cover - compiled by numba
    """BatchWorld._lend_probes' test of which robots are within reach of a wall or the dock (into ``near``);
    lanes no longer within reach give their probe back (parked in the void).  Returns (pymunk must step:
    a lane is within reach or a probe went back, lanes needing a probe, free probes).

    ``reach``: the arenas' middles (x, y) and (near_half, near_dock_y, near_dock_x); ``probing``: lane_probe,
    probe_lane, probe_row, io, void, near (BatchWorld._probe_state).
    """
    midx, midy, lim = reach
    lane_probe, probe_lane, probe_row, io, void, near = probing
    near_half, near_dock_y, near_dock_x = lim[0], lim[1], lim[2]
    stepping = False
    need = 0
    for i in range(gx.shape[0]):
        mx = abs(gx[i] - midx[i])
        my = gy[i] - midy[i]
        ni = mx > near_half or abs(my) > near_half or (my < near_dock_y and mx < near_dock_x)
        near[i] = ni
        p = lane_probe[i]
        if ni:
            stepping = True
            need += p < 0
        elif p >= 0:
            stepping = True
            probe_lane[p] = -1
            io[probe_row[p], 0] = void[p, 0]
            io[probe_row[p], 1] = void[p, 1]
            lane_probe[i] = -1
    free = 0
    for p in range(probe_lane.shape[0]):
        free += probe_lane[p] < 0
    return stepping, need, free


@_jit
def assign_probes(gx, gy, probing):  # pragma: no cover - compiled by numba
    """The lanes within reach without a probe take the free ones (both in ascending order), and every lent
    probe is put at its robot's pose (``io``, pymunk's batch buffer of body positions)."""
    lane_probe, probe_lane, probe_row, io, _, near = probing
    p = 0
    for i in range(near.shape[0]):
        if near[i] and lane_probe[i] < 0:
            while probe_lane[p] >= 0:
                p += 1
            probe_lane[p] = i
            lane_probe[i] = p
    for q in range(probe_lane.shape[0]):
        i = probe_lane[q]
        if i >= 0:
            io[probe_row[q], 0] = gx[i]
            io[probe_row[q], 1] = gy[i]


@_jit
def contact_codes(pairs, probe_ids, probe_of_id, side_ids, side_of, probe_lane, out):  # pragma: no cover
    """BatchWorld._contact_codes: lane * 5 + side of each (probe body, side body) pair of pymunk ids, in either
    order (``probe_ids``, ``side_ids``: sorted; ``probe_of_id``, ``side_of``: their indices) into ``out``."""
    last = probe_ids.shape[0] - 1
    for j in range(pairs.shape[0]):
        a = pairs[j, 0]
        b = pairs[j, 1]
        i = min(np.searchsorted(probe_ids, a), last)
        if probe_ids[i] != a:
            a, b = b, a
            i = min(np.searchsorted(probe_ids, a), last)
        out[j] = probe_lane[probe_of_id[i]] * 5 + side_of[np.searchsorted(side_ids, b)]


@_inline
def _docking_accepted(x, y, rh, speed, c):  # pragma: no cover - compiled by numba
    """BatchWorld._docking_accepted for one lane: the dock's front face, head-on within the angle, slowly."""
    on_front = y >= c[1] and x >= c[2] and x <= c[3]
    a = np.degrees(rh) - -90.0 + 180.0
    head_on = abs((a - 360.0 * np.floor(a * (1.0 / 360.0))) - 180.0) <= c[4]
    slow = speed > 0 and speed <= c[5]
    return on_front and head_on and slow


@_jit
def events(idx, blocked, bang, noise, wall, dock, state, speed, turn, fuel, c, out):  # pragma: no cover
    """The rest of BatchWorld.step after pymunk's contacts: the blocked Targets turn (``bang``: the
    arctan2 towards the centre), robots that touched a wall or the dock are parked (in pymunk's pose only),
    Robot-Target collisions, wall collisions, dockings, fuel, and who ran dry or tracked.

    ``state``: rh, gx, gy, ox, oy, rx, ry, th, tx, ty; ``c``: BatchWorld._event_consts; ``out``: (4, n),
    the collided, docked, dry and tracking rows (every lane's set).
    """
    rh, gx, gy, ox, oy, rx, ry, th, tx, ty = state
    out[:] = False
    reach_, half, t_step = c[0], c[6], c[7]
    for b in range(blocked.shape[0]):
        i = blocked[b]
        t = bang[b] + np.radians(noise[i])
        t = t - _TWO_PI * np.floor((t + np.pi) * _INV_TWO_PI)
        sin_t, cos_t = _sincos(t)
        tx[i] = tx[i] + t_step * cos_t
        ty[i] = ty[i] + t_step * sin_t
        th[i] = t
    for lanes in (wall, dock):
        for i in lanes:
            gx[i] = ox[i] + half
            gy[i] = oy[i] + half
    collided, docked, dry, tracking = out[0], out[1], out[2], out[3]
    for i in idx:
        dx = tx[i] - rx[i]
        dy = ty[i] - ry[i]
        collided[i] = np.sqrt(dx * dx + dy * dy) < reach_
    for i in wall:
        collided[i] = True
    for i in dock:
        if _docking_accepted(rx[i], ry[i], rh[i], speed[i], c) and not collided[i]:
            docked[i] = True
        else:
            collided[i] = True
    idle, per_ips, per_dps, t_min, t_max = c[8], c[9], c[10], c[11], c[12]
    for i in idx:
        f = fuel[i] - (idle + per_ips * abs(speed[i]) + per_dps * abs(turn[i]))
        fuel[i] = f
        going = not collided[i]
        dry[i] = f <= 0.0 and going and not docked[i]
        dx = tx[i] - rx[i]
        dy = ty[i] - ry[i]
        d = np.sqrt(dx * dx + dy * dy)
        tracking[i] = d >= t_min and d <= t_max and going


# ----------------------------------------------------------------- the agent loop (runner._play_episode)
@_jit
def active_lanes(active, group, n_groups, slots, rx, ry, tx, ty, geom, idx, bounds, dy, dx):  # pragma: no cover
    """The active lanes into ``idx``, those of group 0 first, then group 1, ... (``bounds``: where each
    group starts), and the arguments of the arctangents of the directions their sensors need: Target
    (``slots[0]``), nearest point of the dock (``slots[1]``), middle of the dock's front (``slots[2]``),
    direction ``s`` of the ``j``-th lane at ``s * m + j`` (-1: not needed).  Returns m, the active lanes."""
    m = 0
    for g in range(n_groups):
        bounds[g] = m
        for i in range(active.shape[0]):
            if active[i] and group[i] == g:
                idx[m] = i
                m += 1
    bounds[n_groups] = m
    for j in range(m):
        i = idx[j]
        x = rx[i]
        y = ry[i]
        if slots[0] >= 0:
            dy[slots[0] * m + j] = ty[i] - y
            dx[slots[0] * m + j] = tx[i] - x
        if slots[1] >= 0:
            dy[slots[1] * m + j] = min(y, geom[3]) - y
            dx[slots[1] * m + j] = min(max(x, geom[1]), geom[2]) - x
        if slots[2] >= 0:
            dy[slots[2] * m + j] = geom[7] - y
            dx[slots[2] * m + j] = geom[6] - x
    return m


@_inline
def _bit_length(n):  # pragma: no cover - compiled by numba
    """int.bit_length of a small positive n."""
    k = 0
    while n >> k:
        k += 1
    return k


@_inline
def _lowest_bit(mask):  # pragma: no cover - compiled by numba
    """matcher.lowest_bit of one uint64 (64 for 0, as there)."""
    k = 0
    while k < 64 and ((mask >> np.uint64(k)) & _ONE) == 0:
        k += 1
    return k


@_inline
def _strongest(flat, base, B, valid, bins, planes):  # pragma: no cover - compiled by numba
    """CompiledPolicies.decide with conflict='strongest' for one situation: (rank, full match).  The rule
    matching every condition, else (CompiledPolicies._best_partial) the one satisfying the most, counted
    bit-sliced in ``planes`` (bit_length(S) words), the strongest of equals in both cases."""
    match = _ALL
    for s in range(bins.shape[0]):
        match &= flat[base + s * B + bins[s]]
    if match != 0:
        return _lowest_bit(match), True
    planes[:] = 0
    for s in range(bins.shape[0]):
        carry = flat[base + s * B + bins[s]] & valid
        for b in range(planes.shape[0]):
            nxt = planes[b] & carry
            planes[b] ^= carry
            carry = nxt
    cand = valid
    for b in range(planes.shape[0] - 1, -1, -1):
        narrowed = cand & planes[b]
        if narrowed != 0:
            cand = narrowed
    return _lowest_bit(cand), False


@_jit
def decide_lanes(lanes, a0, m, ang, slots, world, sensors, policy, turn, speed, logged, trace, k,
                 t):  # pragma: no cover - compiled by numba
    """runner._decide with conflict='strongest' for one controller's active ``lanes`` (positions ``a0``...
    in :func:`active_lanes`' order): sense, match, set the commands, and if ``logged`` (the learner) write
    step ``t`` of episode ``k`` into its ``trace``: bins, rule, full (``runner.Trace``'s arrays) and fired.

    ``ang``: the arctangents (:func:`atan2_into`) of the directions (radians, :func:`active_lanes`' layout); ``world``: rx, ry,
    rh, tx, ty, th, fuel, geom; ``policy``: the flat bit table, its stride per policy and per sensor, valid
    rules, each lane's policy, turn and speed of every (policy, rank), rank -> rule.
    """
    rx, ry, rh, tx, ty, th, fuel, geom = world
    flat, stride, B, valid, lane_policy, turn_of, speed_of, rank_to_rule = policy
    tr_bins, tr_rule, tr_full, fired = trace
    S = sensors[0].shape[0]
    bins = np.empty(S, dtype=np.uint8)
    planes = np.empty(_bit_length(S), dtype=np.uint64)
    for j in range(lanes.shape[0]):
        i = lanes[j]
        pos = a0 + j
        t_dir = np.degrees(ang[slots[0] * m + pos]) if slots[0] >= 0 else 0.0
        q_dir = np.degrees(ang[slots[1] * m + pos]) if slots[1] >= 0 else 0.0
        d_dir = np.degrees(ang[slots[2] * m + pos]) if slots[2] >= 0 else 0.0
        _sense_lane(sensors, rx[i], ry[i], rh[i], tx[i], ty[i], th[i], fuel[i], t_dir, q_dir, d_dir, geom, bins)
        p = lane_policy[i]
        rank, full = _strongest(flat, p * stride, B, valid[p], bins, planes)
        turn[i] = turn_of[p * 64 + rank]
        speed[i] = speed_of[p * 64 + rank]
        if logged:
            rule = rank_to_rule[p, rank]
            tr_bins[k, t, i, :] = bins
            tr_rule[k, t, i] = rule
            tr_full[k, t, i] = full
            fired[i, k] |= _ONE << np.uint64(rule)


@_jit
def tally(k, active, events, steps, tracked, collided, docked, dry):  # pragma: no cover - compiled by numba
    """runner._play_episode's bookkeeping of a step: its ``events`` (BatchWorld.step_compiled's rows collided,
    docked, dry, tracking) into episode ``k``'s columns, every lane's as there; the lanes that collided, docked or
    ran dry stop."""
    for i in range(active.shape[0]):
        steps[i, k] += active[i]
        tracked[i, k] += events[3, i]
        collided[i, k] |= events[0, i]
        docked[i, k] |= events[1, i]
        dry[i, k] |= events[2, i]
        if events[0, i] or events[1, i] or events[2, i]:
            active[i] = False


# ----------------------------------------------------------------- the evaluator (evaluate.FuelEvaluator)
@_jit
def experiences(per, mine, fired, payoff, rule, bins, full):  # pragma: no cover - compiled by numba
    """FuelEvaluator._experience of every individual (lanes ``[i*per, (i+1)*per)``) of a Tracking or Docking
    learner, one individual's rows after the other's.

    Its episodes (``mine``, (L, K)) in (lane, episode) order, their ``fired`` and ``payoff``; the steps
    whose rule was its (``rule`` >= 0) in those episodes, in (episode, step, lane) order, their bins, rule,
    full and episode (numbered as its episodes are listed).  Returns (episode starts, fired, payoff,
    decision starts, bins, rule, full, episode): individual ``i``'s rows are ``starts[i]:starts[i+1]``.
    """
    L, K = mine.shape
    T = rule.shape[1]
    P = L // per
    epmap = np.full((L, K), -1, dtype=np.int64)
    e_starts = np.zeros(P + 1, dtype=np.int64)
    for i in range(L):
        for k in range(K):
            if mine[i, k]:
                e_starts[i // per + 1] += 1
    for p in range(P):
        e_starts[p + 1] += e_starts[p]
    out_fired = np.empty(e_starts[P], dtype=np.uint64)
    out_payoff = np.empty(e_starts[P], dtype=np.float64)
    for p in range(P):
        c = 0
        for i in range(p * per, (p + 1) * per):
            for k in range(K):
                if mine[i, k]:
                    out_fired[e_starts[p] + c] = fired[i, k]
                    out_payoff[e_starts[p] + c] = payoff[i, k]
                    epmap[i, k] = c
                    c += 1
    # Decisions: counted per individual, then written in the trace's own order (an individual's rows
    # come in its (episode, step, lane) order), each individual at its own cursor.
    d_starts = np.zeros(P + 1, dtype=np.int64)
    for k in range(K):
        for t in range(T):
            for i in range(L):
                if rule[k, t, i] >= 0 and epmap[i, k] >= 0:
                    d_starts[i // per + 1] += 1
    for p in range(P):
        d_starts[p + 1] += d_starts[p]
    n, S = d_starts[P], bins.shape[3]
    out_bins = np.empty((n, S), dtype=np.uint8)
    out_rule = np.empty(n, dtype=np.int64)
    out_full = np.empty(n, dtype=np.bool_)
    out_ep = np.empty(n, dtype=np.int64)
    cursor = d_starts[:P].copy()
    for k in range(K):
        for t in range(T):
            for i in range(L):
                if rule[k, t, i] >= 0 and epmap[i, k] >= 0:
                    p = i // per
                    j = cursor[p]
                    cursor[p] = j + 1
                    for s in range(S):
                        out_bins[j, s] = bins[k, t, i, s]
                    out_rule[j] = rule[k, t, i]
                    out_full[j] = full[k, t, i]
                    out_ep[j] = epmap[i, k]
    return e_starts, out_fired, out_payoff, d_starts, out_bins, out_rule, out_full, out_ep
