"""Navigation top level: float64 golden model of ALGORITHMS.md 8 (and the replay order of 9).

Ties the CS maneuver filter (:mod:`mcahrs.golden.cs`), the attitude EKF
(:mod:`mcahrs.golden.attitude`) and geodetic -> NED (:mod:`mcahrs.golden.geo`) together:
alignment, the history ring, the IMU / GPS / magnetometer steps, the output record, and
:func:`run`, a batch replay of a :class:`mcahrs.samples.Recording`.

Each step either succeeds or raises an :class:`mcahrs.errors.McaError` subclass with the
state unchanged (the documented exceptions: ``BadDtError`` from the IMU step re-anchors
the IMU time; a CS axis update of the GPS step that fails numerically is raised after the
fix's step 7, choice 22).

Choices where ALGORITHMS.md leaves room (checked against the spec as of its "Times" and
"Yaw alignment" paragraphs, the robust modes as of its "velocity step test" with the anchor
before (``v_pre``, *pre*), the held step's guard, the end of a fault the CS took in (its restart in
every mode the test runs in, when step 6 flags the fix) and the test in every mode but plain (a hold
in the modes other than fuzzy rows: no course observation), GPS step 1's velocity and accuracy
checks, GPS step 4's numerically failed axis update and its end of a position fault the CS took
in with its position reference, ALGORITHMS.md 7's course gate and its guard, GPS step 3's aid of N and E
once any yaw observation was made (session 26), the step test's held fixes' positions in fuzzy rows
(session 27), GPS step 4's position hold in fuzzy rows (its ``d`` the predicted change on the fixes the step
test holds and the fix after them, as revised) and section 5's rows applied beside the N/E pair's (session
28), the history ring's spacing, which follows the fixes, 20-50 ms (session 29), the step test's
variance scale ``lambda`` and the return's size window's lower bound (session 31), GPS step 3's hold of
the newest entry's acceleration for at most ``2 dt_h`` (session 33), and step by step against the C
core in tests/python/test_nav_golden_vs_c.py)
------------------------------------------------------------------------------------------
1.  Times (ALGORITHMS.md 8): every configured duration (``grav_period_s``, ``gps_timeout_s``,
    ``init_still_s``, ``init_timeout_s``, ``cs_lag_s``, ``imu_dt_max_s``, the CS ``dt_max_s``
    and ``tau_a_s`` in the "4 tau_a" limit) becomes integer microseconds once,
    ``round(x * 1e6)``, and every time comparison is made in integer us. The alignment window
    time is the integer sum of its samples' ``dt_us``. Formulas (``exp(-age/tau_a)``,
    ``r_acc``) use the configured seconds.
2.  ``MCA_HIST_LEN`` is 48 (ALGORITHMS.md 8; ``Nav(hist_len=)`` takes another size). History
    interval accumulator: reset to 0 (not carried over) at each push. Lookup: smallest
    ``|t_entry - t|``, ties to the older; ``t <`` oldest entry time, or an empty ring, is a miss.
    The spacing ``dt_h`` (``Nav.hist_dt_us``, integer us; session 29): ``MCA_HIST_DT_US`` (20 000) at
    ``reset``; an entry is pushed when the accumulated interval reaches the spacing of the moment
    (``>=``; a spacing that shrank below the interval accumulated so far pushes at the next sample).
    It is set on every fix past step 3's gap check: not the home fix (step 2), not a CS
    re-initialisation after a gap (step 3), but every other fix that reaches step 7, so also one
    whose CS update failed numerically (choice 22) and one that restarts the CS at the end of a
    fault (choices 23, 24, 28), which do not do steps 5-6 (the spec's parenthesis names only the
    home fix and the gap as the fixes that do not "go through steps 4-6", and the spacing is the span
    this fix's IMU increments needed, which neither a failed update nor a restart changes). It is
    set after step 6 and before step 7 (after step 4 on those fixes), so step 3's hold (choice 14)
    reads the spacing the fixes before left: ``s = t_imu - t_lastfix`` (the newest IMU time, the one
    the IMU step keeps, a ``BAD_DT`` re-anchor's included; ``t_lastfix`` before step 7), ``dt_h = 250
    min(max(s // 10 000, 80), 200)`` when ``0 <= s < 2 000 000``, else ``MCA_HIST_DT_MAX_US``
    (50 000): ``t_imu`` before ``t_lastfix``, or no IMU sample yet (no newest IMU time: taken as
    before it), counts as ``s >= 2 s``. Aligned or not. A step 1 error, or an input check of step 4,
    leaves it as it was.
3.  Lost-GPS roll/pitch timer: due when ``t_us - t_last >= grav_period_us``; ``t_last`` is the
    alignment sample's time, then the time of the last due attempt (made or skipped). The
    centripetal term uses the bias after this sample's propagation (propagation leaves ``b``
    unchanged) and the NE velocity of the last accepted fix (the home fix or a CS
    re-initialisation included); ``r_acc`` uses the horizontal ``sigma_a0`` and ``tau_a``.
4.  A roll/pitch or yaw observation whose Kalman update fails (SINGULAR / NONFINITE) counts
    as skipped; it never changes the status of the step (IMU / GPS / mag) that made it.
5.  GPS step: accuracies that are NaN, infinite or <= 0 use the configured defaults; the
    altitude range is checked only when the fix has altitude (an absent value is not looked
    at). Step 1 in the spec's order: fix_type, position range, the velocity flagged present
    (every component's finiteness before any component's range, so NONFINITE wins over RANGE;
    "over 1000 m/s": ``|v| > 1000``), the three accuracies after the defaults (``h_acc``,
    ``v_acc``, ``s_acc`` in that order, each whether the fix uses it or not; "its square is not a
    finite float > 0": the accuracy as a float32, squared in float32, is inf or 0, so a subnormal
    square is accepted, :func:`check_accuracies`), then the time. The golden INS runs the same
    checks (ALGORITHMS.md 10, GNSS update step 1), on the accuracies before its noise minimum.
    ``a_last`` (the lost-GPS decay start; the spec names it only in IMU step 6) is the CS ``a``
    after the update, set with step 5's compensation acceleration (so not by a fix whose CS update
    failed, choice 22), 0 after a home fix or a CS re-initialisation. The yaw-uncertainty term of
    step 5 uses ``P[2][2]`` as it is at the GPS step, before that step's observations.
6.  Course over ground needs the NE-velocity flag (``speed_mps``/``course_rad`` are not used);
    its ``s_acc`` is the fix's effective ``s_acc`` (fix value, else ``gps_vel_sigma_mps``). It
    uses the history entry nearest ``t_fix`` (skipped on a miss; saturation does not matter to
    it) and is made even when the roll/pitch one was skipped.
7.  Presets (ALGORITHMS.md 8): every preset has a yaw source, so every preset sets
    ``yaw0_var_rad2 = (30 deg)^2``; ``AttConfig()`` alone keeps the no-yaw-source (180 deg)^2,
    and a caller who sets ``yaw_source = 0`` by hand sets ``yaw0_var_rad2`` too. All presets:
    horizontal CS ``sigma_a0 = 1.0``, ``tau_a = 2`` on N, E and D (the vertical ``sigma_a0``
    stays the section-2 default 0.3).
8.  Magnetometer: non-finite is NONFINITE even when it is not the yaw source; ``|m_b| == 0`` is
    skipped with status OK; the one-per-``grav_period`` limit runs on the magnetometer's
    ``t_us`` and only observations attempted (not zero vectors) restart it.
9.  Flags: ``saturated`` is sticky (any accepted IMU sample with a ``dt``, aligned or not);
    ``grav_skipped`` and ``hist_miss`` describe the latest roll/pitch attempt (course-over-
    ground lookups do not touch them); ``yaw_unobserved``: ``yaw_source == 0``, no yaw
    observation yet, or the last one more than 10 s of IMU time ago (its time is the newest
    IMU time when it was made; the yaw alignment counts as one). Before home / alignment the
    outputs are the zero state (q = [1, 0, 0, 0], P = 0, CS x = P = 0); ``rp_T`` and ``gps_T``
    are NaN until first set, and ``gps_T`` of an axis keeps its last value when that axis is
    not updated.
10. Output Euler order is (roll, pitch, yaw); CS P diagonals are flattened axis-major:
    ``[N_pp, N_vv, N_aa, E_pp, E_vv, E_aa, D_pp, D_vv, D_aa]``.
11. Roll/pitch attempts counted (made / skipped): every GPS-step attempt when aligned (mode 2
    without a usable previous fix counts as skipped; a CS re-initialisation makes none) and
    every due lost-GPS attempt.
12. Yaw alignment (ALGORITHMS.md 7): the first yaw observation *made*; one that would be
    skipped (tilt above ``max_tilt_obs``, a history miss for course over ground, speed below
    ``cog_min_speed``) does not align. Once per filter (``reset`` re-arms it), but for the course
    gate's guard (choice 26), which aligns yaw again.
13. Robust modes (ALGORITHMS.md 5) at the navigation level: each CS axis keeps its own robust
    memory, coasting mark and IMU-aided prior (``cs.CsAxis.mem``, ``out``, ``prior``;
    ``cs.Cs3.predict_aided`` / ``update_robust``), configured by ``cs_h.robust`` / ``cs_v.robust``;
    the attitude filter one memory, ``att.robust``, for every roll/pitch observation (GPS step and
    lost GPS); yaw observations are plain (the course gate aside, choice 26). A roll/pitch observation
    the robust mode rejects is *made* (status OK, ``rp_T`` its T, counted in ``n_grav_made``): section 8
    counts as skipped only an update that fails (the gravity gate, SINGULAR, NONFINITE), and section 5
    says a rejection returns OK. The output flags carry each CS axis' alarm after the last fix
    (``FLAG_ALARM_N << axis``). The reported ``gps_T`` is each update's tested T.
14. IMU increments (GPS step 3): ring entries as consecutive (previous end, end] intervals, the
    oldest one only as the start of the next; the interval's end past the newest entry holds the
    newest entry's acceleration for at most twice the spacing, ``2 dt_h`` (session 33, one ``dt_h``
    before; ``dt_h`` is choice 2's, the value the fixes before this one set, whatever spacing the
    newest entry was pushed at; the bound is inclusive: an end exactly ``2 dt_h`` past is held);
    any saturated entry that overlaps the interval, or one held, turns the aid off for all axes.
15. The IMU-aided N and E (GPS step 3, session 26): "once any yaw observation was made" is a yaw
    observation or the yaw alignment taken since the reset (``t_yaw_us`` set; the first one made is
    always the alignment, which the course gate does not refuse), however long ago: the
    ``yaw_unobserved`` flag's 10 s (choice 9), the coasting marks and the velocity step test's hold
    play no part. With ``yaw_source = 0`` none is ever made, so N and E are never aided; D takes the
    increments whenever they exist (choice 14), as before.
16. The AKF ``q_scale`` (section 5, step 3: "applied by the filter to its process noise at its
    next predict") is the memory's current value, applied at every predict until an update changes
    it: on a CS axis it multiplies the whole Q of section 2 (Singer block, q44, q55), ordinary or
    coasting (not the coast's IMU term, not the test prior's S); on the attitude filter Qd's angle
    block (section 7) at every propagation.
17. A CS re-initialisation (GPS step 3, ``T > dt_max``) restarts the axes as at home: their robust
    memories, coasting marks and priors are cleared (the attitude memory and the last flagged fix
    are kept); the step test's ``n = 0`` (no increments carry the anchor over the gap), and at step 7
    (when aligned) the fix's N, E velocity is the anchor when it has one (no update left it out), with
    *pre* clear (the test did not run on it). Only this re-initialisation sets ``n = 0``: the restarts
    at the end of a fault (choices 23, 24) leave ``n`` as it is (``_cs_restart`` does not touch it).
18. Coasting marks (section 2): after each update an axis is ``out`` when it was rejected or left
    out the velocity row it had (this update's rows: the memory's ``n_removed`` of its rows, which an
    update that keeps a row sets to 0; a lock-up reset applies every row); an axis not updated
    (mask 0) keeps its mark, and a predict without increments neither uses nor clears it. The coast's
    start shift (the prior less the predicted ``[p + eps_p, v + eps_v]``) applies with ``coast`` set,
    the axis not marked before this update, and a prior.
19. Flagged fixes (GPS step 6), N and E only: FTA, AKF, fuzzy with ``fuzzy_reject`` 0 or 1:
    ``detected`` or the tested ``T > chi2_m(0.01)``; IGG-III: rejected, or the velocity row (when
    present) at weight 0; fuzzy rows: the axis' coasting mark after the update; plain: never. The
    ``tau_a`` hold is ``t_fix - t_lastflag < tau_a_us`` of ``cs_h`` (the flagged fix itself
    included), integer us; it holds GPS-step roll/pitch observations only (lost-GPS ones are not
    fixes), and the course observation is held for the flagged fix alone. A fix the velocity step test
    held (choice 20) gives no course observation either, in every mode, and is not flagged by it: its
    roll/pitch observation and the ``tau_a`` hold go by the flag alone (in fuzzy rows a held fix's
    velocity rows are out, so it is flagged anyway).
20. Velocity step test (GPS step 3): it runs with ``cs_h`` in any robust mode but plain (its
    ``robust.mode``; N and E share it), N and E both aided (both have increments), N and E velocity
    in the fix, and an anchor; ``dv``, ``qa``, ``qc`` are N's and E's (the same variances). "It is the
    return when it fails and [the reverse-step conditions], and, while holding, [the raw step back],
    otherwise *armed*": with no fix held, the reverse step is the return only when armed. The guard
    takes the hold count before this fix: in fuzzy rows ``n < reject_reset_n``; in the other modes
    ``n T < 20 s`` as a time comparison in integer us (ALGORITHMS.md 8, Times), ``n * T_us <
    20_000_000`` with ``T_us`` this fix's interval. What a hold does: in fuzzy rows the N and E
    velocity rows go out (``vel_held``, choice 21) and the detectors' ``D`` rise to at least 2, and a
    disarmed release lowers them to at most 1; in the other modes neither (the update and its
    memories are those of the fix not held), and the held fix gives no course observation (choice
    19). The fault's end (a disarmed release, not one by the positions, choice 27) restarts the CS in
    every mode when step 6 then flags the fix (choice 23). A fix neither held, nor the return, nor the
    first after a hold leaves *armed* as it was. The detectors' ``D`` changes are made before the predict
    and the updates (so the N/E pair's plans see them). ``v_last`` is the previous accepted fix's velocity
    (held or not). "The test ran on it": its conditions held, whatever its outcome; otherwise the anchor
    needs both N and E with the velocity row applied (their coasting marks clear after the update). The
    anchor before: with no fix held, the agreement ``|v_fix - (v_pre + dv)|^2 <= k C`` uses the same ``k``
    (``chi2_2(1e-4)``) and ``C`` (the current anchor's ``V_a``) as the step; it only clears a failure (so
    a fix it clears is neither held nor the return). While holding, the nearer-the-step test ``2 s . s0 >=
    |s0|^2`` fails a fix whatever ``k C`` says (the return is then judged on ``r`` as before). ``v_pre =
    v_p`` on every fix the test ran on and did not hold (the return and the fix after a hold included); a
    held fix keeps ``v_pre`` and *pre*. At step 7 nothing of the test is written before alignment (the
    anchor, *pre* and ``V_a`` stay; the test runs aligned only). The variance scale ``lambda`` (session
    31): 1 at construction (``mca_nav_init``; ``reset``, which only the constructor calls), never reset by
    a CS (re-)initialisation, a gap, a restart or a re-alignment. It is read at the test's start: ``C =
    lambda C_u``, ``C_u = s_acc^2 + V_a + qa T^2``, ``C_r = lambda (2 s_acc^2 + qa T^2)``, and every
    comparison with ``k C`` or a ``C_r`` uses the scaled ones (the fail test, the anchor before's
    agreement, the return's raw step back, *armed*); the positions' ``V_e`` (choice 27) is not scaled.
    After the test, on a fix with no fix held at its start (``n = 0``) and ``|s|^2 <= k C`` (it passes on
    its own, so is neither held nor the return), ``lambda = min(1, max(1/4, (31/32) lambda + |s|^2 / (64
    C_u)))`` from that fix's ``|s|^2`` and ``C_u``, in float64 (the C's float32 arithmetic is not
    modelled). A fix the test does not run on leaves it as it was. The return's size window: ``q >= 0.5
    |s0|^2`` always, ``q <= 2.25 |s0|^2`` unless the positions say the held step (choice 27).
21. The N/E pair (section 5) is formed when N and E both run fuzzy rows, both have a prior and both
    take position and velocity; each plan is ``robust.fuzzy_rows_failed`` on the axis' memory (read
    only), and a held fix's velocity rows are added to both pairs. A plan whose test fails
    numerically (SINGULAR, NONFINITE: that axis' own update then fails the same way) sends no row
    out of the other axis.
22. A CS axis update that fails numerically (GPS step 4: SINGULAR, NONFINITE; only a corrupted
    covariance does, the inputs being bounded by step 1): every axis is updated from the same
    predicted CS (``cs.Cs3.update_robust_partial``); a failed one keeps its predicted state, its robust
    memory as it was before the update (the step test's ``D`` changes of step 3 stay) and its coasting
    marks, and loses its prior; the others are updated. The status raised is the first failing axis'
    (N, E, D). Step 3's test state stays as the test left it (held or not), steps 5-6 are skipped (no
    compensation, no flag, no observation, no count), and step 7 is done: ``t_lastfix = t_cs = t_fix``,
    the fix velocity remembered, and the anchor (when aligned, not held) with "both the N and E
    updates applied their velocity" false when either of them failed. ``a_last`` stays the last
    fix's (it is step 5's; the lost-GPS decay then runs from this fix's time). ``gps_T`` of a failed axis
    keeps its last successful update's T since the CS filter (re)started (home or re-initialisation),
    NaN if there was none (ALGORITHMS.md 8, output).
23. The end of a fault the CS took in (GPS step 3): "a fix the test judged the fault's end" is one the
    step test ran on, did not hold, and found the return or the first fix after a hold, and left
    disarmed (in fuzzy rows the one whose N and E ``D`` it lowers to at most 1; an armed release is not
    an end, nor is a release by the positions, choice 27), in every mode the test runs in. It restarts the
    CS when "step 6 then *flags*" the fix: the flag step 6 computes (choice 19) from this fix's N and E
    updates of step 4, taken after the update and before the restart (which clears the marks and memories
    it reads), each axis by its own robust configuration (both ``cs_h``'s; the D update flags nothing). In
    fuzzy rows and IGG-III it is that axis' coasting mark ``out`` set after step 4 ("the N or E update of
    step 4 leaving its velocity row out or rejecting the update": for IGG-III the same as step 6's
    rejection or velocity weight 0), and an axis whose update failed numerically keeps the mark it had
    (choice 22, as the spec says); in FTA, AKF and fuzzy reject or inflate the mode's ``detected`` or its
    tested ``T > chi2_m(0.01)`` (``m`` that update's rows), and a failed axis (no detection, no T) flags
    nothing. The flag is only the restart's condition: the restarted fix does not become the last flagged
    one (steps 5-6 are not done), so it starts no ``tau_a`` hold. The restart is choice 17's, after the
    update: every axis (D included) re-initialised at the fix's position (N and E at the position
    reference when near it, choice 25) and velocity, memories, coasting marks and priors cleared,
    ``a_last`` 0, ``n`` as the test left it (0: the hold has just ended, or none was); the reported
    ``gps_T`` stay the update's tested T (the axes were updated), and a later failed update reports NaN
    until one succeeds (the CS restarted). Steps 5-6 are skipped (no compensation, no flagged fix, no
    roll/pitch or course observation, no count); step 7 is done as after an update: the test ran on the
    fix, so its velocity is the anchor (``V_a = s_acc^2``) with *pre* set (``v_pre`` the pre-fault anchor
    carried on, as the test left it). With another axis failing numerically on the same fix, the restart
    is done and that axis' status then raised.
24. The end of a position fault the CS took in (GPS step 4): N and E each by their own robust config
    (both ``cs_h``'s), the rule's axes those whose mode is FTA, AKF, IGG-III or fuzzy with
    ``fuzzy_reject`` 0 or 1. ``z`` is the fix's NED position on the axis, ``p_0`` / ``p`` the CS
    position before / after step 3's predict (coasting or not), ``eps_p`` the predicted GPS-error
    state, ``T`` the fix interval, ``R`` the receiver model's position variance (``h_acc^2`` without
    it). The jump's ``d`` is ``T (v + v_prev) / 2``, ``v`` this fix's N (E) velocity and ``v_prev`` that
    of the last fix step 7 remembered (``prev_vel`` with its mask: the home fix, a gap's
    re-initialisation, a restarted or held fix, or one whose update failed numerically, all reach step
    7), when both have the NE-velocity flag and the fix is not one the step test holds after the
    hold's first; ``p - p_0`` otherwise (the spec's "either fix has no N/E velocity", and "On a fix the
    step test holds after the hold's first (``n > 1`` after step 3) ``d = p - p_0``, the predicted
    change, as without velocities"): the step test's ``n`` as step 3's test left it on this fix (a fix
    it held has ``n >= 1``, any other 0), in every mode the test runs in. Such a fix's jump is
    otherwise like any other's: counted past the bound, and it may return. The hold's first fix
    (``n = 1``) and the first fix after a hold take the velocities' ``d``, the latter with the last held
    fix's velocity as ``v_prev`` (the spec's "of the last": step 7 remembers a held fix's velocity too;
    the position hold's ``d`` does not, choice 28).
    The first fix after a (re-)start has ``z_prev`` NaN, so no jump whichever ``d``. The bullets in the spec's
    order: the jump is added (when ``z_prev`` is not NaN and past the bound), then ``J`` decays (this
    fix's jump included), then ``z_prev = z``, then the return test with that ``J``: the axis returns when
    (this fix's ``j`` was a jump, that is this fix added its ``j`` to that axis' ``J``, or ``4 J^2 <=
    B`` on both N and E, each axis with its own ``J`` and ``B``: no position fault pending on either,
    session 25) and ``nu^2 > B`` and ``4 J^2 <= nu^2`` (its own). Both axes' ``J`` are updated before
    either is tested (``_position_return`` runs the bullets on N and E, then the return on each). A fix
    whose ``j`` is undefined (the first after a (re-)initialisation, ``J`` 0 then) or within the bound
    may thus return when nothing is pending on N or E: a CS that drifted from clean fixes restarts from
    them; an axis whose CS drifted while the other axis' fault is pending does not (the restart
    re-initialises N and E together). The return is decided before the update and
    acted on after it: the restart is choice 23's (every axis re-initialised at the fix, or N and E at
    the position reference, choice 25; memories,
    coasting marks, priors, ``a_last``; the step test's ``n`` as it is, so a fix it held stays held and
    step 7 writes no anchor), which also sets ``z_prev`` NaN and ``J = 0``, as the
    home start and both other restarts do (``_cs_restart``); the ``z_prev = z`` of this fix is not
    kept. Steps 5-6 are skipped, step 7 is done as after an update (``_step7``, after the restart):
    when aligned and the fix not held, *pre* is ``ran``, the step test's own result on this fix (it
    ran when its conditions held, whatever its outcome: a fix that returns may have been tested, and
    one the test held writes nothing), and the anchor exists when the fix has N and E velocity and
    the test ran on it or both the N and E updates were made (neither failed numerically), their
    coasting marks being read after the restart cleared them (a velocity row step 4 left out is then
    no bar: the CS restarted at the fix's velocity); an axis' numerical failure on the same fix is
    raised after it. On a step 1 error, or an input check of step 4, the memory is as it was.
25. The position reference (GPS step 4, session 25): one ``p_ref`` per N and E axis and one flag *ref* for
    both (kept with ``z_prev`` and ``J``, ``_PosJumps``; N and E share ``cs_h``'s robust mode, so both run
    the rule or neither). Only the rule's axes (choice 24) touch them: in plain and fuzzy rows *ref* is
    never set, so their restarts are always at the fix. On a fix with *ref* set (aligned: only a quiet
    fix sets it, and alignment is never undone), each axis, after ``J``'s forgetting and ``z_prev = z``,
    does ``p_ref += d`` with the jump's own ``d`` (the trapezoid, or the predicted change ``p - p_0``) and
    is *near* when ``(z - p_ref)^2 <= B`` (``z`` the fix's NED, ``B`` the axis' material bound of this
    fix); ``p_ref`` is carried on a far fix too. Both restarts of a fix (step 3's end of a fault the CS
    took in and step 4's return: "as step 3's", so the same re-initialisation) start N and E at ``p_ref``
    when *ref* was set and both N and E are near on this fix: ``x = [p_ref, v_fix, 0, 0, 0]``, ``P =
    diag(sigma_p_m^2, v0_var, a0_var, sigma_p_m^2, sigma_v^2)``, D at the fix's ``ned``; otherwise all
    three at ``ned`` as before. Every (re-)initialisation (home, gap, either end of a fault) clears *ref*
    (``_cs_restart`` renews ``_PosJumps``). A fix is *quiet* when: it does not restart the CS (steps 3-4;
    a gap's re-initialisation never gets here), aligned, the rule ran on N and E and neither of them
    summed a jump nor has ``4 J^2 > B`` (``J`` after this fix's jump and forgetting, each axis its own
    ``B``), step 6's flag (choice 19, ``_flags_fix``) of this fix's N and E updates is clear, and the step
    test's ``n`` after step 3 is 0; it then sets ``p_ref`` to N and E's CS position ``x[0]`` after step 4
    and sets *ref*. A fix whose N or E update failed numerically (choice 22; steps 5-6 not done) is not
    excluded: the spec's conditions do not name it; a failed axis flags nothing (choice 23), and its
    ``p`` is the predicted one it keeps.
26. The course gate and its guard (ALGORITHMS.md 7, yaw observations; GPS step 6): with ``att.robust.mode``
    not plain and yaw already observed (``yaw_aligned``), a course observation with ``nu^2 > chi2_1(1e-4)
    (P[2][2] + sigma^2)`` is refused, nothing changed: ``nu = wrap(psi_m - psi)``, ``psi`` the yaw of the
    history entry's ``q_d`` the observation uses, ``P[2][2]`` the attitude ``P`` before it (``chi2_1`` of
    :func:`mcahrs.golden.robust.chi2_quantile`). The tilt skip is tested first (either way nothing
    changes and the observation counts). ``n_cog`` counts the course observations made (aligned, GPS step
    6's conditions: the fix not flagged nor held, NE velocity, speed ``>= cog_min_speed``; and the history
    entry found) and not taken (refused, skipped for tilt, or a failed update), in a row, saturating at 10;
    one taken (update or yaw alignment) sets it to 0, as does ``reset``. The guard is read before the
    observation: ``n_cog == 10`` (the ten before it not taken) and either ``t_imu - t_yaw > 30 s`` with the
    velocity step test's *armed* clear as step 3 of this fix left it (never set in plain ``cs_h``, where
    the test does not run) or, *armed* or not, ``t_imu - t_yaw > 120 s`` (both in integer us, strictly
    greater; ``t_yaw``: the newest IMU time at the last yaw observation taken, choice 9) make this
    observation the yaw alignment of choice 12 (tilt skip included) instead of the gated update, whatever
    the gate would say. The 120 s bound covers a hold that released with no fault in, which leaves
    *armed* set until the next hold. The counting and the guard are the same in plain mode, with no
    gate. The magnetometer yaw has no gate and neither reads nor changes ``n_cog``.
27. The held fixes' positions (GPS step 3, velocity step test, sessions 27 and 32), fuzzy rows only
    (``cs_h``'s ``robust.mode`` fuzzy with ``fuzzy_reject`` 2). The test is read only while holding (``n >
    0`` before this fix, as the other holding rules): with ``e`` (N, E) and ``t_e`` as the held fixes
    before this one left them, the fix also fails when ``2 e . s0 >= t_e |s0|^2`` and ``(e . s0)^2 > k
    |s0|^2 V_e``, ``k`` the step's own ``k`` of a fix while holding, ``chi2_2(0.005)`` (the 2-DOF
    quantile, though ``e . s0`` is one number: the spec's ``k``), ``V_e = 2 w^2 + 2 sigma_p^2 t_e /
    tau_p``, ``w`` the white part of this fix's ``h_acc`` (``min(h_acc, gps_pos_white_m)`` with the
    receiver model, the whole ``h_acc`` without it: the N/E position variance of this fix's step 4),
    ``sigma_p``, ``tau_p`` ``cs_h``'s ``sigma_p_m``, ``tau_p_s``. With ``e = 0``, ``t_e = 0`` (nothing
    summed) it neither fails nor releases (below; ``V_e > 0``): the hold's second fix sees nothing summed,
    so the positions speak from its third fix (one interval summed) on. Such a fix is the return when, on
    ``r``, ``u . s0 < 0``, ``(u . s0)^2 >= 0.5 q |s0|^2``, ``q >= 0.5 |s0|^2`` and ``|r|^2 > chi2_2(1e-4)
    C_r`` (``C_r`` scaled by ``lambda``, choice 20) hold, the window's upper bound ``q <= 2.25 |s0|^2``
    not asked ("unless the positions say the held step": both conditions above; the lower bound holds
    either way, session 31); a fix that fails only by the other rules keeps the whole window. The fix is
    *released by the positions* (session 32) when ``(e . s0)^2 <= k |s0|^2 V_e`` and ``(t_e |s0|^2 - e .
    s0)^2 > chi2_2(1e-4) |s0|^2 V_e`` (never with the rule above), from the same ``e``, ``t_e``: it fails
    by no rule (the anchor's included), so it is the first fix after the hold, never the return; it is
    disarmed (N and E take ``D = min(D, 1)``, as at any disarmed end of a hold) and no fault's end
    (``vst.ended`` clear: step 6's flag of it restarts nothing, choice 23). The sum, "after the test"
    (step 3, before the predict and the CS update of step 4; a fix the gap re-initialises skips the test
    and is not held), on a fix the test held (``h = n > 0`` after it; a held fix is aligned, the test runs
    aligned only): the hold's first (``h = 1``) sets ``e = 0``, ``t_e = 0`` and adds nothing; each one
    after it (``h > 1``) adds ``T (v_fix + v_last) / 2 - (p_fix - p_last)`` to ``e`` and ``T`` (this fix's
    interval, that of step 3's predict) to ``t_e``; every held fix, and no other, then sets ``p_last`` to
    its N and E position, step 3's ``ned`` (section 6, from home). A fix not held (the return, the first
    fix after a hold, a fix the test does not run on) changes neither ``e`` nor ``t_e``; ``e`` and ``t_e``
    are not cleared by a CS start or by the end of a hold either (only read while holding, and every
    hold's first fix restarts them). ``p_last`` is step 4's memory of the last position, ``z_prev``
    (``_PosJumps``), which every fix sets in fuzzy rows (the position hold, choice 28, after these sums
    have read it: the held fix's "sets ``p_last``" is that write) and every CS (re-)initialisation makes
    NaN (``_cs_restart``). It is read only on a fix held after another held fix (``h > 1``), so it is the
    fix before's position unless that fix restarted the CS: the position hold's restart (choice 28) may
    fall on a fix the step test holds, and the next held fix then sums a NaN. The model lets it propagate:
    ``e`` is NaN for the rest of that hold, so the positions say nothing, neither the held step nor a
    release (every comparison with NaN is false), until the next hold's first fix restarts the sum (the C
    core does the same: a golden model that skipped the NaN term, or restarted the sum there, parted from
    it in tests/python/test_nav_golden_vs_c.py, CAR_POS_BURST_RESTART_HELD). ``v_last`` is step 7's
    remembered velocity, the held fix ``h - 1``'s (step 7 is done on every fix past step 1, a numerical
    failure's too), which has N and E velocity (the test ran on it). A fix whose CS axis update fails
    numerically keeps what step 3 wrote (choice 22); a step 1 error changes nothing.
28. The position hold (GPS step 4, session 28) and section 5's rows beside the N/E pair's, fuzzy rows only
    (``cs_h``'s ``robust.mode`` fuzzy with ``fuzzy_reject`` 2; ``_PosHold``, ``_position_hold``,
    ``_position_hold_after``).
    Section 5: while alarmed, with no row past its own level (section 5's returns are past it, so with
    only returns failing every row but the pair's is applied, as before) the update is rejected unless
    the N/E pair has a row out of it (the other axis' plan, the velocity step test's velocity rows, the
    position hold's position rows); then no other row goes out (the rows the last two updates left out
    stay out only "while any row fails") and the rest are applied, every row out being a rejection as
    before. The caller's rows ride in the memory (``RobustState.caller_out``, the spec's ``started``), set
    by the hold before the update and cleared by it (and by the model after a failed one); they go out of
    that update whether or not the N/E pair is
    formed (a fix without N/E velocity, or N and E without the IMU-aided test: the C core does the same,
    checked by hand with saturated IMU samples inside a held burst, the pair then unformed: a golden
    model that set them only with the pair parted from it at the first such fix). A 1-row update (no N/E
    velocity) held is rejected either way: its one row out is every row out, and alarmed with no row
    failing and no pair's row it is rejected too.
    The state: ``z_prev`` is ``_PosJumps``' (shared with choice 27's ``p_last``); the spec stores ``p_a``,
    ``s_p`` and *anchor* in the position rule's ``p_ref``, ``J`` and *ref*, which that rule never touches
    in fuzzy rows (choices 24, 25) and the hold never outside them, so the model keeps them apart, in
    ``_PosHold``, with ``t_h``, *holding* and *taken* (session 33); every CS (re-)initialisation (home, a
    gap, step 3's end of a fault, the hold's restart) starts it afresh (the three flags clear), and
    ``z_prev`` NaN.
    Before the update, on every fix past step 3 (a gap's re-initialisation skips it; aligned or not):
    after step 3's test, its sums and the predict, ``d`` is the trapezoid of this fix's and step 7's last
    N, E velocity, or ``p - p_0`` when either has none or ``n > 0`` before or after step 3's test (a fix the
    step test holds, its first included, and the fix after a held one: the trapezoid would carry the held
    velocity; ``n`` before is as the last fix left it, a gap's re-initialisation 0, a restart's kept; choice
    24's rule keeps ``n > 1`` after), ``dz = z - z_prev`` (``z`` step 3's ``ned``), then ``z_prev = z``;
    ``p_a``, ``e``, ``r`` only when aligned and *anchor*. "While *holding*" for ``t'`` is *holding* at
    the fix's start. ``w^2`` is this fix's N/E position variance of step 4 (the receiver model's
    ``min(h_acc, gps_pos_white_m)^2``, ``h_acc^2`` without it), ``V = 2 (w^2 + sigma_p^2 t' / tau_p)``;
    ``g2``, ``g4`` the 2-DOF quantiles (``e . s_p`` is one number, but the spec's). The step back is
    computed once, before the hold's decision, with the ``s_p`` the fix found (never when ``s_p = 0``,
    *anchor* clear, not aligned, or ``dz`` not finite); the window ``| |r|^2 - 1.25 |s_p|^2 | <= |s_p|^2``
    as written (``0.25 |s_p|^2 <= |r|^2 <= 2.25 |s_p|^2``). The guard reads N's position row's
    ``n_removed`` (row 0) before this update against ``cs_h.robust.reject_reset_n`` (``<``: 0 makes the
    significance the only way to stay held). Held: N's and E's ``caller_out`` of row 0 and ``D =
    max(D, 2)``; released: *holding*, *anchor* and *taken* clear, ``s_p`` and ``t_h`` kept, ``D = min(D,
    1)`` on N and E when the step test's ``n`` after step 3 is 0. These ``D`` changes come after the step
    test's (so a hold of either alarms) and before the N/E pair's plans, as the step test's (choice 20).
    After the update: "the update of N or E left its position row out" is N's or E's memory with
    ``n_removed[0] > 0`` after step 4 (a rejection or a lock-up reset counts as the memory says: a reset
    clears it; an axis whose update failed numerically keeps the memory it had, choice 22). The restart
    is read first: a fix that stepped back (so aligned, with *anchor* at its start), whose *holding* was
    clear at its start or whose *taken* was set at its start (session 33; a fix that steps back while
    holding without *taken* only ends the hold, whatever its update did), and whose N or E update left
    its position row out, restarts the CS after step 4 as step 3's end of a fault does (choice 23: every
    axis at the fix, from the position reference never, since *ref* is never set in fuzzy rows;
    memories, coasting marks and priors cleared, ``a_last`` 0, the step test's ``n`` as it is; steps 5-6
    skipped, step 7 done as after an update, choice 24's anchor rule). Any restart of the fix (this one,
    or step 3's end of a fault the CS took in) skips the part after the update. Otherwise, *holding*
    (after the decision: a kept hold) with N's and E's memories both at ``n_removed[0] = 0`` after the
    update (only section 5's whole-update guard applies a held fix's position rows) sets *taken* (session
    33; the hold goes on, nothing else changes; *taken* is read at a fix's start, so the fix that sets it
    is no restart); aligned and not *holding* (after the decision: a fix released this time is not
    holding): a fix that stepped back sets ``s_p = 0``; then ``j = z - p_a`` (``p_a`` as carried before
    the update; *anchor* as the decision left it) and the onset when *anchor*, the position row out,
    ``|j|^2 > g4 V`` (``V`` of this fix, ``t' = T``) and no step back: *holding*, ``s_p = j``, ``t_h =
    0``; otherwise ``p_a = z``, *anchor* set (so a released fix, or any fix not holding, re-anchors at
    itself). A step 1 error, or an input check of step 4, leaves all of it as it was.
    Checked against the C core (tests/python/test_nav_golden_vs_c.py): with section 5's rule before session
    28 the model parts from it on 11 of the 12 fuzzy-rows cases of before; *holding* at the fix's start for
    the restart, against *holding* read after the decision (CAR_POS_VEL_DRIFT: that reading restarts the CS
    at the burst's end, which steps back while holding, and parts from the C at the fix after it); the
    trapezoid as ``d`` on the hold's first fix or the fix after a hold (the rule before its revision) starts
    a hold from a velocity spike's trapezoid and holds clean fixes 6.5 s (CAR_SPIKE_HELD_2HZ,
    CAR_SPIKE_BEFORE_2HZ).
"""

from __future__ import annotations

import copy
import math
from collections import deque
from dataclasses import dataclass, field, fields, replace
from typing import Any, NamedTuple

import numpy as np

from mcahrs.errors import (
    BadArgError,
    BadConfigError,
    BadDtError,
    BadMaskError,
    McaError,
    NonFiniteError,
    NotInitError,
    NullError,
    RangeError,
    SingularError,
    TimeBackwardsError,
)
from mcahrs.golden import attitude as att
from mcahrs.golden import geo
from mcahrs.golden.cs import MASK_POS, MASK_VEL, AxisInc, Cs3, CsAxisConfig
from mcahrs.golden.robust import FUZZY_ROWS, RobustReport, RobustState, chi2_quantile
from mcahrs.samples import GNSS_HAS_ALT, GNSS_HAS_VEL_D, GNSS_HAS_VEL_NE, Recording

__all__ = [
    "COMP_CS",
    "COMP_GPS_DIFF",
    "COMP_OFF",
    "FIX_VEL_MAX_MPS",
    "FLAG_ALARM_N",
    "FLAG_ALIGNED",
    "FLAG_GPS_LOST",
    "FLAG_GRAV_SKIPPED",
    "FLAG_HIST_MISS",
    "FLAG_HOME_SET",
    "FLAG_SATURATED",
    "FLAG_YAW_UNOBSERVED",
    "MCA_HIST_DT_MAX_US",
    "MCA_HIST_DT_US",
    "MCA_HIST_LEN",
    "STATUS_CODES",
    "YAW_COG",
    "YAW_MAG",
    "YAW_NONE",
    "YAW_UNOBSERVED_US",
    "HistEntry",
    "Nav",
    "NavConfig",
    "NavOutput",
    "check_accuracies",
    "check_fix_velocity",
    "replay_order",
    "run",
    "status_code",
]

MCA_HIST_LEN = 48  # history ring entries (ALGORITHMS.md 8)
YAW_UNOBSERVED_US = 10_000_000  # no yaw observation for this long: yaw unobserved
MCA_HIST_DT_US = 20_000  # the history spacing dt_h at initialisation and its minimum, us (ALGORITHMS.md 8)
MCA_HIST_DT_MAX_US = 50_000  # ... its maximum, us: s of 2 s or more since the last fix (session 29)
HIST_DT_SPAN_US = 2_000_000  # ... s from here on (or t_imu before t_lastfix) gives MCA_HIST_DT_MAX_US

COMP_OFF, COMP_CS, COMP_GPS_DIFF = 0, 1, 2  # comp_mode
YAW_NONE, YAW_MAG, YAW_COG = 0, 1, 2  # yaw_source

FLAG_ALIGNED = 1 << 0
FLAG_HOME_SET = 1 << 1
FLAG_GPS_LOST = 1 << 2
FLAG_YAW_UNOBSERVED = 1 << 3
FLAG_GRAV_SKIPPED = 1 << 4  # last roll/pitch observation attempt was skipped
FLAG_SATURATED = 1 << 5  # a saturated accelerometer sample has been seen
FLAG_HIST_MISS = 1 << 6  # last history lookup missed
FLAG_ALARM_N = 1 << 7  # the N axis' fuzzy alarm after the last fix; << 1: E, << 2: D (ALGORITHMS.md 5)

FLAG_LEVEL = 0.01  # GPS step 6: FTA, AKF and fuzzy flag a fix whose tested T exceeds chi2_m(this)
STEP_LEVEL_FAIL = 1e-4  # GPS step 3, velocity step test: chi2_2(this) with no fix held, and the raw step
STEP_LEVEL_HELD = 0.005  # ... chi2_2(this) while fixes are held
STEP_HOLD_MAX_US = 20_000_000  # ... the guard of the modes other than fuzzy rows: n T < 20 s (integer us)
POS_RETURN_LEVEL = 1e-4  # GPS step 4, the end of a position fault the CS took in: chi2_1(this)
POS_JUMP_FORGET = 5.0  # ... the sum of the jumps decays over this many tau_p
HOLD_LEVEL_STEP = 0.005  # GPS step 4, the position hold (fuzzy rows): g2 = chi2_2(this), the step's level
HOLD_LEVEL_WANDER = 1e-4  # ... g4 = chi2_2(this): the onset and the held step within the receiver's wander
HOLD_D_HELD = 2.0  # ... a held fix's N and E detectors take D = max(D, this): they alarm
HOLD_D_RELEASE = 1.0  # ... a release with the step test holding nothing: D = min(D, this)
COG_GATE_LEVEL = 1e-4  # ALGORITHMS.md 7, the course gate: nu^2 > chi2_1(this) (P[2][2] + sigma^2) refuses
COG_MISSED_MAX = 10  # ... n_cog, the course observations not taken in a row, stays at this; the guard's count
COG_GUARD_US = 30_000_000  # ... the guard: no yaw observation taken for more than this (IMU time, us)
COG_GUARD_ARMED_US = 120_000_000  # ... or for more than this, the step test armed or not (IMU time, us)

G_DEFAULT = 9.80665  # gravity before home when not configured
FIX_VEL_MAX_MPS = 1000.0  # MCA_FIX_VEL_MAX_MPS: a larger fix velocity component is RANGE (GPS step 1)

# ALGORITHMS.md 4 status codes; OK is 0.
STATUS_CODES: dict[type[McaError], int] = {
    NullError: 1,
    BadDtError: 2,
    NonFiniteError: 3,
    SingularError: 4,
    BadMaskError: 5,
    BadArgError: 6,
    BadConfigError: 7,
    TimeBackwardsError: 8,
    RangeError: 9,
    NotInitError: 10,
}


def status_code(exc: McaError) -> int:
    """Integer status code of an McaError (ALGORITHMS.md 4)."""
    for cls in type(exc).__mro__:
        if cls in STATUS_CODES:
            return STATUS_CODES[cls]
    raise TypeError(f"no status code for {type(exc).__name__}")


def _us(seconds: float) -> int:
    return int(round(seconds * 1e6))


# --------------------------------------------------------------------------------------
# Configuration (ALGORITHMS.md 8 table)
# --------------------------------------------------------------------------------------


_YAW0_WITH_SOURCE = math.radians(30.0) ** 2  # ALGORITHMS.md 7: yaw0 with a yaw source


def _preset_cs_h() -> CsAxisConfig:
    """Horizontal CS of every preset (ALGORITHMS.md 8): sigma_a0 = 1.0, tau_a = 2."""
    return replace(CsAxisConfig.horizontal(), sigma_a0_mps2=1.0, tau_a_s=2.0)


def _preset_cs_v() -> CsAxisConfig:
    """Vertical CS of every preset: the section-2 defaults with tau_a = 2."""
    return replace(CsAxisConfig.vertical(), tau_a_s=2.0)


def _preset_att() -> att.AttConfig:
    """Attitude configuration of every preset: a yaw source, so yaw0 = (30 deg)^2."""
    return replace(att.AttConfig(), yaw0_var_rad2=_YAW0_WITH_SOURCE)


@dataclass(frozen=True)
class NavConfig:
    """Navigation configuration. The plain default is the ground-vehicle preset. The robust modes
    (ALGORITHMS.md 5) are ``cs_h.robust``, ``cs_v.robust`` (and ``coast``) and ``att.robust``."""

    cs_h: CsAxisConfig = field(default_factory=_preset_cs_h)  # CS axes N, E
    cs_v: CsAxisConfig = field(default_factory=_preset_cs_v)  # CS axis D
    att: att.AttConfig = field(default_factory=_preset_att)
    comp_mode: int = COMP_CS  # 0 off, 1 CS maneuver compensation, 2 GPS velocity differencing
    yaw_source: int = YAW_COG  # 0 none, 1 magnetometer, 2 course over ground
    cs_lag_s: float = 0.2  # lag of the CS acceleration behind the truth (pairing delay)
    gps_timeout_s: float = 1.5  # no fix for this long: GPS lost
    grav_period_s: float = 0.1  # observation period while GPS is lost or never seen
    nogps_rp_var_rad2: float = 0.05**2  # roll/pitch observation variance added when GPS is lost (base)
    nogps_centripetal: int = 1  # without GPS, remove w x [V, 0, 0] (V: last fix speed)
    gravity_mps2: float = 0.0  # > 0: this constant; 0: normal gravity at home
    imu_dt_max_s: float = 0.1  # longest accepted IMU step
    init_still_s: float = 1.0  # averaging window of the initial alignment
    init_gyro_still_rps: float = 0.05  # max gyro norm to count as still
    init_acc_still_mps2: float = 0.5  # max | |f| - g | to count as still
    init_timeout_s: float = 5.0  # align from whatever was averaged after this long
    accel_sat_mps2: float = 156.9  # any |f_i| >= this: saturated sample
    gps_pos_sigma_m: float = 2.5  # used when a fix gives no h_acc
    gps_alt_sigma_m: float = 5.0  # used when a fix gives no v_acc
    gps_vel_sigma_mps: float = 0.2  # used when a fix gives no s_acc
    mag_declination_rad: float = 0.0
    mag_yaw_sigma_rad: float = 0.05
    cog_min_speed_mps: float = 3.0
    cog_sigma0_rad: float = 0.05
    gps_test_imu: int = 1  # robust modes test the CS update against the IMU-aided prediction
    imu_acc_sigma_mps2: float = 0.3  # IMU acceleration error std of that prediction
    # the part of it that persists over a coast (ALGORITHMS.md 2, coasting; GPS step 3): the CS axes'
    # coast variance (cs_h.coast / cs_v.coast) and the velocity step test's anchor variance
    coast_acc_sigma_mps2: float = 0.15
    # Receiver model (ALGORITHMS.md 8, GPS step 4): > 0, the white part of the position error, R =
    # min(accuracy, white)^2; the rest is the CS GPS-error state's (sigma_p_m, tau_p_s). 0: R = accuracy^2.
    gps_pos_white_m: float = 0.0
    gps_alt_white_m: float = 0.0

    @classmethod
    def ground_vehicle(cls) -> NavConfig:
        """The plain default: yaw from course over ground above 3 m/s, cs_lag 0.2."""
        return cls()

    @classmethod
    def fixedwing(cls) -> NavConfig:
        """Fixed-wing preset: yaw from course over ground above 5 m/s, a_max_h 8, cs_lag 0.2."""
        base = cls()
        return replace(
            base,
            cs_h=replace(base.cs_h, a_max_mps2=8.0),
            yaw_source=YAW_COG,
            cog_min_speed_mps=5.0,
            cs_lag_s=0.2,
        )

    @classmethod
    def multirotor(cls) -> NavConfig:
        """Multirotor preset: yaw from the magnetometer, a_max_h 5, cs_lag 0.3, no centripetal term."""
        base = cls()
        return replace(
            base,
            cs_h=replace(base.cs_h, a_max_mps2=5.0),
            yaw_source=YAW_MAG,
            cs_lag_s=0.3,
            nogps_centripetal=0,
        )

    @classmethod
    def preset(cls, name: str) -> NavConfig:
        """A preset by name: ``ground``, ``fixedwing`` or ``multirotor``."""
        makers = {"ground": cls.ground_vehicle, "fixedwing": cls.fixedwing, "multirotor": cls.multirotor}
        if name not in makers:
            raise BadConfigError(f"unknown preset {name!r}; known: {', '.join(makers)}")
        return makers[name]()

    def validate(self) -> None:
        """Raise BadConfigError on any value out of range."""
        if not isinstance(self.cs_h, CsAxisConfig) or not isinstance(self.cs_v, CsAxisConfig):
            raise BadConfigError("cs_h / cs_v must be CsAxisConfig")
        if not isinstance(self.att, att.AttConfig):
            raise BadConfigError("att must be AttConfig")
        self.cs_h.validate()
        self.cs_v.validate()
        self.att.validate()
        if self.comp_mode not in (COMP_OFF, COMP_CS, COMP_GPS_DIFF):
            raise BadConfigError(f"comp_mode must be 0, 1 or 2, got {self.comp_mode!r}")
        if self.yaw_source not in (YAW_NONE, YAW_MAG, YAW_COG):
            raise BadConfigError(f"yaw_source must be 0, 1 or 2, got {self.yaw_source!r}")
        for flag in ("nogps_centripetal", "gps_test_imu"):
            if getattr(self, flag) not in (0, 1):  # True/False compare equal to 1/0
                raise BadConfigError(f"{flag} must be 0 or 1, got {getattr(self, flag)!r}")
        nonneg = (
            "cs_lag_s",
            "nogps_rp_var_rad2",
            "gravity_mps2",
            "gps_pos_white_m",
            "gps_alt_white_m",
            "coast_acc_sigma_mps2",
        )
        flags = ("cs_h", "cs_v", "att", "comp_mode", "yaw_source", "nogps_centripetal", "gps_test_imu")
        for f in fields(self):
            if f.name in flags:
                continue
            v = getattr(self, f.name)
            if isinstance(v, bool) or not isinstance(v, (int, float, np.integer, np.floating)):
                raise BadConfigError(f"{f.name} must be a number, got {v!r}")
            if not math.isfinite(v):
                raise BadConfigError(f"{f.name} must be finite, got {v!r}")
            if f.name == "mag_declination_rad":
                continue
            if f.name in nonneg:
                if v < 0.0:
                    raise BadConfigError(f"{f.name} must be >= 0, got {v!r}")
            elif v <= 0.0:
                raise BadConfigError(f"{f.name} must be > 0, got {v!r}")
        for name in ("grav_period_s", "gps_timeout_s", "init_still_s", "init_timeout_s"):
            if _us(getattr(self, name)) <= 0:
                raise BadConfigError(f"{name} is shorter than 1 us")


# --------------------------------------------------------------------------------------
# History ring and output record
# --------------------------------------------------------------------------------------


class HistEntry(NamedTuple):
    """One history entry: IMU time at its end, mean specific force, q at its end, saturated."""

    t_us: int
    f_b: tuple[float, float, float]
    q: att.Quat
    saturated: bool


@dataclass(frozen=True)
class NavOutput:
    """Output record (ALGORITHMS.md 8, output)."""

    t_us: int  # newest IMU time
    q: np.ndarray  # (4,) q_nb
    euler: np.ndarray  # (3,) roll, pitch, yaw
    gyro_bias: np.ndarray  # (3,) rad/s
    pos_ned: np.ndarray  # (3,) CS extrapolated to t_us
    vel_ned: np.ndarray
    acc_ned: np.ndarray
    att_P_diag: np.ndarray  # (6,)
    cs_P_diag: np.ndarray  # (9,) N(p, v, a), E(p, v, a), D(p, v, a)
    rp_T: float  # last roll/pitch NIS
    gps_T: np.ndarray  # (3,) last CS NIS per axis
    flags: int
    n_grav_made: int
    n_grav_skipped: int
    n_yaw_made: int


def _finite3(v: Any) -> tuple[float, float, float]:
    """Three floats from a sequence (not checked for finiteness); BadArgError if impossible."""
    try:
        if len(v) != 3:
            raise BadArgError(f"expected 3 values, got {len(v)}")
        return (float(v[0]), float(v[1]), float(v[2]))
    except (TypeError, ValueError) as exc:
        raise BadArgError(f"expected 3 numbers, got {v!r}") from exc


@dataclass
class _StepTest:
    """State of the velocity step test (ALGORITHMS.md 8, GPS step 3)."""

    v_a: np.ndarray = field(default_factory=lambda: np.zeros(2))  # the anchor velocity, N and E
    V_a: float = 0.0  # its variance, an axis
    n: int = 0  # fixes held
    s0: np.ndarray = field(default_factory=lambda: np.zeros(2))  # the step that started the last hold
    anchor: bool = False  # v_a exists
    armed: bool = False  # a return is armed
    # the anchor before v_a, carried on to the last fix the test ran on and did not hold
    v_pre: np.ndarray = field(default_factory=lambda: np.zeros(2))
    pre: bool = False  # the test ran on the previous fix (v_pre is its)
    # fuzzy rows (choice 27): the held fixes' velocity less their position change, summed (N, E), and
    # the time it spans; restarted at the hold's first fix
    e: np.ndarray = field(default_factory=lambda: np.zeros(2))
    t_e: float = 0.0
    # the test judged this fix the fault's end: the return, or the first fix after a hold, disarmed (not
    # released by the positions)
    ended: bool = False
    # the variance scale (session 31): 1 at mca_nav_init, kept through CS restarts and re-alignments;
    # C and C_r are scaled by it, in [1/4, 1] (choice 20)
    lam: float = 1.0


@dataclass
class _PosJumps:
    """The end of a position fault the CS took in (ALGORITHMS.md 8, GPS step 4): N and E's memory."""

    z_prev: np.ndarray = field(default_factory=lambda: np.full(2, math.nan))  # the last fix's position
    J: np.ndarray = field(default_factory=lambda: np.zeros(2))  # the sum of the fixes' jumps
    # the position reference (session 25): the CS position of the last quiet fix, carried on by the
    # fixes' d; ref: p_ref exists (cleared with the rest by every CS (re-)initialisation)
    p_ref: np.ndarray = field(default_factory=lambda: np.zeros(2))
    ref: bool = False


@dataclass
class _PosHold:
    """The position hold (ALGORITHMS.md 8, GPS step 4, session 28; fuzzy rows, choice 28): N and E's anchor
    ``p_a`` carried on by the fixes' ``d``, the held step ``s_p``, the hold's time ``t_h`` and the flags
    *anchor* (``p_a`` exists), *holding* and *taken* (the hold's step went into the CS, session 33);
    ``z_prev`` is ``_PosJumps``'. Every CS (re-)initialisation starts it afresh (``_cs_restart``), the three
    flags clear."""

    p_a: np.ndarray = field(default_factory=lambda: np.zeros(2))
    s_p: np.ndarray = field(default_factory=lambda: np.zeros(2))
    t_h: float = 0.0
    anchor: bool = False
    holding: bool = False
    taken: bool = False  # session 33: a held fix's update kept N's and E's position rows in (the guard's)


class _HoldFix(NamedTuple):
    """What the position hold found on a fix before its update (choice 28), for after it."""

    ran: bool  # fuzzy rows: the rule ran on this fix
    stepped_back: bool  # the fix steps back (aligned and *anchor* at its start)
    was_holding: bool  # *holding* at the fix's start
    was_taken: bool  # *taken* at the fix's start (session 33: a step back then restarts the CS)
    z: np.ndarray  # the fix's N and E position
    V: float  # the receiver's position error over t', 2 (w^2 + sigma_p^2 t' / tau_p)


class _PosRule(NamedTuple):
    """What GPS step 4's position rule found on a fix, before the update (choices 24, 25)."""

    returned: bool  # N or E returns: the CS restarts after step 4
    near: bool  # ref set and both N and E near p_ref: a restart on this fix starts N and E at p_ref
    calm: bool  # the rule ran on N and E and neither jumped nor has a fault pending (quiet's part)


class _Fix(NamedTuple):
    t_us: int
    lat_e7: int
    lon_e7: int
    alt_mm: int
    vel: tuple[float, float, float]
    h_acc: float
    v_acc: float
    s_acc: float
    fix_type: int
    flags: int


def _get(fix: Any, name: str) -> Any:
    if isinstance(fix, (np.void, dict)):
        return fix[name]
    return getattr(fix, name)


def _accuracy(v: Any, default: float) -> float:
    """ALGORITHMS.md 8 GPS step: NaN (or not finite, or <= 0) uses the configured default."""
    x = float(v)
    return x if (math.isfinite(x) and x > 0.0) else default


def check_fix_velocity(vel: Any, present: Any) -> None:
    """ALGORITHMS.md 8, GPS step 1 (and 10, GNSS update step 1): a velocity component flagged present
    that is not finite is NonFiniteError (checked on every present component first, so it wins over
    the range); a finite one over ``FIX_VEL_MAX_MPS`` in magnitude is RangeError."""
    v = np.asarray(vel, dtype=np.float64).reshape(3)[np.asarray(present, dtype=bool)]
    if not np.all(np.isfinite(v)):
        raise NonFiniteError("velocity flagged present is not finite")
    if np.any(np.abs(v) > FIX_VEL_MAX_MPS):
        raise RangeError(f"fix velocity {v} m/s: a component over {FIX_VEL_MAX_MPS:g} m/s")


def check_accuracies(**accuracies: float) -> None:
    """ALGORITHMS.md 8, GPS step 1 (and 10, GNSS update step 1): every accuracy, after the defaults,
    used by the fix or not, whose square is not a finite float > 0 is BadArgError. "float" is the
    spec's float32: the square of the accuracy as a float32, rounded to float32, must be finite and
    above 0 (a subnormal square is a float > 0; the spec's "under ~1e-19" is where squares leave the
    normal range, which a flush-to-zero FPU takes as 0)."""
    with np.errstate(over="ignore", under="ignore"):
        for name, acc in accuracies.items():
            a = np.float32(acc)
            sq = a * a
            if not (np.isfinite(sq) and sq > 0.0):
                raise BadArgError(f"{name} = {acc!r}: its square is not a finite float > 0")


def _white(accuracy: float, white: float) -> float:
    """ALGORITHMS.md 8 GPS step 4, the receiver model: the std taken as the position rows' R."""
    return min(accuracy, white) if white > 0.0 else accuracy


# --------------------------------------------------------------------------------------
# The navigation filter
# --------------------------------------------------------------------------------------


class Nav:
    """Navigation filter state and its steps (ALGORITHMS.md 8)."""

    def __init__(self, cfg: NavConfig | None = None, hist_len: int = MCA_HIST_LEN) -> None:
        cfg = NavConfig() if cfg is None else cfg
        if not (isinstance(hist_len, int) and hist_len >= 1):
            raise BadConfigError(f"hist_len must be a positive int, got {hist_len!r}")
        self.hist_len = hist_len
        if not isinstance(cfg, NavConfig):
            raise BadConfigError("cfg must be a NavConfig")
        cfg.validate()
        self.cfg = cfg
        # Durations in integer us, once (ALGORITHMS.md 8, Times).
        self._grav_period_us = _us(cfg.grav_period_s)
        self._gps_timeout_us = _us(cfg.gps_timeout_s)
        self._init_still_us = _us(cfg.init_still_s)
        self._init_timeout_us = _us(cfg.init_timeout_s)
        self._cs_lag_us = _us(cfg.cs_lag_s)
        self._imu_dt_max_us = _us(cfg.imu_dt_max_s)
        self._cs_dt_max_us = min(_us(cfg.cs_h.dt_max_s), _us(cfg.cs_v.dt_max_s))
        self._tau_a_us = (_us(cfg.cs_h.tau_a_s), _us(cfg.cs_h.tau_a_s), _us(cfg.cs_v.tau_a_s))
        self.reset()

    def reset(self) -> None:
        """Back to the state before the first sample (configuration kept)."""
        cfg = self.cfg
        # IMU time
        self.t_first_us: int | None = None
        self.t_imu_us: int | None = None
        # alignment window
        self.aligned = False
        self.win_f = [0.0, 0.0, 0.0]
        self.win_w = [0.0, 0.0, 0.0]
        self.win_n = 0
        self.win_us = 0
        self.all_f = [0.0, 0.0, 0.0]  # sum of f since the first sample (alignment by timeout)
        self.all_n = 0
        # attitude
        self.q: att.Quat = (1.0, 0.0, 0.0, 0.0)
        self.b: tuple[float, float, float] = (0.0, 0.0, 0.0)
        self.P = np.zeros((6, 6))
        self.yaw_aligned = False  # the first yaw observation aligns yaw (ALGORITHMS.md 7)
        # history ring and its accumulator
        self.hist: deque[HistEntry] = deque(maxlen=self.hist_len)
        self.hist_dt_us = MCA_HIST_DT_US  # the spacing dt_h, set by the fixes (choice 2, session 29)
        self.acc_f = [0.0, 0.0, 0.0]
        self.acc_n = 0
        self.acc_us = 0
        self.acc_sat = False
        # GPS / CS
        self.home: tuple[int, int, int] | None = None
        self.g = cfg.gravity_mps2 if cfg.gravity_mps2 > 0.0 else G_DEFAULT
        self.cs = Cs3(cfg.cs_h, cfg.cs_v)
        self.t_lastfix_us: int | None = None  # == t_cs
        self.cs_T_set = [False, False, False]  # each CS axis updated since the CS (re)started
        self.prev_vel: tuple[float, float, float] = (math.nan, math.nan, math.nan)
        self.prev_has_vel = (False, False, False)
        self.a_last: tuple[float, float, float] = (0.0, 0.0, 0.0)
        # observation timers
        self.t_grav_us = 0  # last lost-GPS roll/pitch attempt
        # a lost-GPS observation made by the last IMU step, completed by the next call
        self.grav_pending: tuple[HistEntry | None, tuple[float, float, float], float] | None = None
        self.t_mag_us: int | None = None  # last magnetometer observation attempt
        self.t_yaw_us: int | None = None  # IMU time of the last yaw observation made
        self.n_cog = 0  # course observations made but not taken, in a row, up to COG_MISSED_MAX (choice 26)
        # reports and flags
        self.rp_T = math.nan
        self.gps_T = [math.nan, math.nan, math.nan]
        self.n_grav_made = 0
        self.n_grav_skipped = 0
        self.n_yaw_made = 0
        self.grav_skipped = False
        self.hist_miss = False
        self.saturated_seen = False
        # robust modes (ALGORITHMS.md 5, 8): the attitude filter's memory of its roll/pitch update
        # (the CS axes keep theirs), the last flagged fix (GPS step 6), the velocity step test
        self.att_mem = RobustState()
        self.t_flag_us: int | None = None
        self.vst = _StepTest()
        self.jumps = _PosJumps()
        self.hold = _PosHold()

    # ----------------------------------------------------------------------------------
    # IMU step
    # ----------------------------------------------------------------------------------
    def imu(self, t_us: int, gyro_rps: Any, accel_mps2: Any) -> None:
        """IMU step (ALGORITHMS.md 8). Raises NonFiniteError, TimeBackwardsError, BadDtError."""
        self._complete_pending()
        t_us = int(t_us)
        w = _finite3(gyro_rps)
        f = _finite3(accel_mps2)
        if not all(math.isfinite(v) for v in w + f):  # step 1
            raise NonFiniteError("IMU sample not finite")
        if self.t_imu_us is None:  # step 2
            self.t_imu_us = self.t_first_us = t_us
            return
        if t_us <= self.t_imu_us:  # step 3
            raise TimeBackwardsError(f"IMU time {t_us} <= {self.t_imu_us}")
        dt_us = t_us - self.t_imu_us
        dt = dt_us * 1e-6
        if dt_us > self._imu_dt_max_us:
            self.t_imu_us = t_us  # re-anchor, nothing else
            raise BadDtError(f"IMU dt {dt} s > {self.cfg.imu_dt_max_s}")
        sat = max(abs(f[0]), abs(f[1]), abs(f[2])) >= self.cfg.accel_sat_mps2
        if not self.aligned:  # step 4
            self._align_step(t_us, dt_us, w, f)
            self.saturated_seen = self.saturated_seen or sat
            self.t_imu_us = t_us
            return
        # step 5 (may raise); the AKF scale of the roll/pitch memory multiplies Qd (choice 16)
        q, P = att.propagate(self.q, self.b, self.P, w, dt, self.cfg.att, self.att_mem.q_scale)
        self.q, self.P = q, P
        self.t_imu_us = t_us
        self.saturated_seen = self.saturated_seen or sat
        self._hist_accumulate(t_us, dt_us, f, sat)
        if self._gps_lost(t_us) and t_us - self.t_grav_us >= self._grav_period_us:  # step 6
            self._lost_gps_observation(t_us, w)

    def _align_step(self, t_us: int, dt_us: int, w: tuple, f: tuple) -> None:
        """ALGORITHMS.md 8, IMU step 4: still blocks judged on their means; all-time mean at timeout."""
        cfg = self.cfg
        for i in range(3):
            self.win_f[i] += f[i]
            self.win_w[i] += w[i]
            self.all_f[i] += f[i]
        self.win_n += 1
        self.all_n += 1
        self.win_us += dt_us
        assert self.t_first_us is not None
        att_var = cfg.att.att0_var_rad2
        if self.win_us >= self._init_still_us:
            n = self.win_n
            f_mean = tuple(v / n for v in self.win_f)
            w_mean = tuple(v / n for v in self.win_w)
            still = (
                math.hypot(*w_mean) <= cfg.init_gyro_still_rps
                and abs(math.hypot(*f_mean) - self.g) <= cfg.init_acc_still_mps2
                and not self._moving_by_gps()
            )
            if still:
                self._align(t_us, f_mean, w_mean, att_var)
                return
            self.win_f, self.win_w, self.win_n, self.win_us = [0.0, 0.0, 0.0], [0.0, 0.0, 0.0], 0, 0
        if t_us - self.t_first_us >= self._init_timeout_us:
            n = self.all_n
            self._align(t_us, tuple(v / n for v in self.all_f), (0.0, 0.0, 0.0), 25.0 * att_var)

    def _moving_by_gps(self) -> bool:
        """The newest fix reports a horizontal speed above 0.5 m/s (ALGORITHMS.md 8, IMU step 4)."""
        if not (self.prev_has_vel[0] and self.prev_has_vel[1]):
            return False
        return math.hypot(self.prev_vel[0], self.prev_vel[1]) > 0.5

    def _align(self, t_us: int, f_mean: tuple, b: tuple, att_var: float) -> None:
        fx, fy, fz = f_mean
        phi = math.atan2(-fy, -fz)
        theta = math.atan2(fx, math.sqrt(fy * fy + fz * fz))
        self.q = att.quat_from_euler(phi, theta, 0.0)
        self.b = b
        self.P = att.initial_covariance(replace(self.cfg.att, att0_var_rad2=att_var))
        self.aligned = True
        self.t_grav_us = t_us  # the no-GPS observation timer starts at the aligning sample

    # ----------------------------------------------------------------------------------
    # History ring (ALGORITHMS.md 8)
    # ----------------------------------------------------------------------------------
    def _hist_accumulate(self, t_us: int, dt_us: int, f: tuple, sat: bool) -> None:
        self.acc_f[0] += f[0]
        self.acc_f[1] += f[1]
        self.acc_f[2] += f[2]
        self.acc_n += 1
        self.acc_us += dt_us
        self.acc_sat = self.acc_sat or sat
        if self.acc_us >= self.hist_dt_us:
            n = self.acc_n
            mean = (self.acc_f[0] / n, self.acc_f[1] / n, self.acc_f[2] / n)
            self.hist.append(HistEntry(t_us, mean, self.q, self.acc_sat))
            self.acc_f = [0.0, 0.0, 0.0]
            self.acc_n = 0
            self.acc_us = 0
            self.acc_sat = False

    def hist_lookup(self, t_us: int) -> HistEntry | None:
        """Entry with the smallest |t_entry - t| (ties: the older); None when t is older than all."""
        if not self.hist or t_us < self.hist[0].t_us:
            return None
        best = self.hist[0]
        best_d = abs(best.t_us - t_us)
        for e in self.hist:  # oldest first: strict < keeps the older on ties
            d = abs(e.t_us - t_us)
            if d < best_d:
                best, best_d = e, d
        return best

    def _set_hist_spacing(self) -> None:
        """The spacing dt_h from this fix's span ``s = t_imu - t_lastfix`` (ALGORITHMS.md 8, history
        ring; choice 2): ``s / 40`` in steps of 250 us, 20-50 ms. Called after GPS step 6 (or step 4 on a
        fix that does not do steps 5-6), before step 7 sets ``t_lastfix`` to this fix's time."""
        assert self.t_lastfix_us is not None
        s = None if self.t_imu_us is None else self.t_imu_us - self.t_lastfix_us
        if s is None or s < 0 or s >= HIST_DT_SPAN_US:
            self.hist_dt_us = MCA_HIST_DT_MAX_US
        else:
            self.hist_dt_us = 250 * min(max(s // 10_000, 80), 200)

    # ----------------------------------------------------------------------------------
    # Observations
    # ----------------------------------------------------------------------------------
    def _gps_lost(self, t_us: int) -> bool:
        return self.t_lastfix_us is None or t_us - self.t_lastfix_us > self._gps_timeout_us

    def _grav_skip(self, hist_miss: bool = False) -> None:
        self.n_grav_skipped += 1
        self.grav_skipped = True
        self.hist_miss = hist_miss

    def _roll_pitch(
        self, entry: HistEntry | None, a_n: tuple[float, float, float], r_acc: float, q_d: att.Quat | None
    ) -> None:
        """Roll/pitch observation from a history entry (None: a history miss).

        q_d None: the entry's q (delayed); otherwise the given attitude (lost-GPS mode: q).
        """
        if entry is None or entry.saturated:
            self._grav_skip(hist_miss=entry is None)
            return
        mem = copy.deepcopy(self.att_mem)
        try:
            res = att.roll_pitch_update(
                self.q,
                self.b,
                self.P,
                np.array(entry.f_b),
                np.array(a_n),
                entry.q if q_d is None else q_d,
                r_acc,
                self.g,
                self.cfg.att,
                mem,
            )
        except McaError:  # choice 4
            self._grav_skip()
            return
        if not res.made:
            self._grav_skip()
            return
        self.att_mem = mem
        self.q, self.b, self.P = res.q, res.b, res.P
        self.rp_T = res.T
        self.n_grav_made += 1
        self.grav_skipped = False
        self.hist_miss = False

    def _yaw(
        self, psi_m: float, sigma2: float, q_d: att.Quat, gate: bool = False, realign: bool = False
    ) -> bool:
        """Yaw observation (ALGORITHMS.md 7); the first one made aligns yaw instead of updating, and so
        does one with ``realign`` (the course gate's guard, choice 26). ``gate``: the course gate
        refuses the update when ``nu^2 > chi2_1(1e-4) (P[2][2] + sigma2)``, ``nu`` at ``q_d``. Returns
        whether the observation was taken (updated or aligned); otherwise nothing changed."""
        if realign or not self.yaw_aligned:
            if abs(att.euler_from_quat(q_d)[1]) > self.cfg.att.max_tilt_obs_rad:
                return False  # skipped like any yaw observation (choice 12)
            self.q, self.P = att.yaw_align(self.q, self.P, psi_m, sigma2)
            self.yaw_aligned = True
        else:
            if gate:
                _, theta_d, psi_d = att.euler_from_quat(q_d)
                if abs(theta_d) > self.cfg.att.max_tilt_obs_rad:
                    return False  # skipped for tilt (as yaw_update would)
                nu = att.wrap_pi(psi_m - psi_d)
                if nu * nu > chi2_quantile(COG_GATE_LEVEL, 1) * (float(self.P[2, 2]) + sigma2):
                    return False  # refused by the course gate, nothing changed
            try:
                res = att.yaw_update(self.q, self.b, self.P, psi_m, sigma2, q_d, self.cfg.att)
            except McaError:  # choice 4
                return False
            if not res.made:
                return False
            self.q, self.b, self.P = res.q, res.b, res.P
        self.n_yaw_made += 1
        self.t_yaw_us = self.t_imu_us
        return True

    def _lost_gps_observation(self, t_us: int, gyro: tuple[float, float, float]) -> None:
        """ALGORITHMS.md 8, IMU step 6 (gyro: this sample's raw gyro)."""
        cfg = self.cfg
        self.t_grav_us = t_us
        a_n = np.zeros(3)
        if cfg.comp_mode == COMP_CS and self.t_lastfix_us is not None:
            age_us = t_us - self.t_lastfix_us
            for i in range(3):
                tau_us = self._tau_a_us[i]
                if age_us <= 4 * tau_us:
                    a_n[i] = self.a_last[i] * math.exp(-age_us / tau_us)
        if (
            cfg.comp_mode in (COMP_CS, COMP_GPS_DIFF)
            and cfg.nogps_centripetal
            and self.t_lastfix_us is not None
            and self.prev_has_vel[0]
        ):
            # Centripetal acceleration of a vehicle moving along its nose at the last fix's
            # ground speed: C_nb(q) (w x [V, 0, 0]) = C_nb(q) [0, w_z V, -w_y V].
            speed = math.hypot(self.prev_vel[0], self.prev_vel[1])
            w = (gyro[0] - self.b[0], gyro[1] - self.b[1], gyro[2] - self.b[2])
            a_n = a_n + att.dcm_from_quat(self.q) @ np.array([0.0, w[2] * speed, -w[1] * speed])
        # Unknown maneuver of variance sigma_a0^2 correlated over tau_a, seen every grav_period.
        r_acc = cfg.nogps_rp_var_rad2 + cfg.cs_h.sigma_a0_mps2**2 * cfg.cs_h.tau_a_s / (
            self.g**2 * cfg.grav_period_s
        )
        entry = self.hist[-1] if self.hist else None
        # made now, completed at the start of the next call (before it changes anything, so at this
        # same attitude q): the firmware spreads the observation over two IMU steps
        self.grav_pending = (entry, (float(a_n[0]), float(a_n[1]), float(a_n[2])), r_acc)

    def _complete_pending(self) -> None:
        """The lost-GPS observation of the last IMU step (ALGORITHMS.md 8, IMU step 6)."""
        if self.grav_pending is not None:
            entry, a_n, r_acc = self.grav_pending
            self.grav_pending = None
            self._roll_pitch(entry, a_n, r_acc, self.q)

    # ----------------------------------------------------------------------------------
    # GPS step
    # ----------------------------------------------------------------------------------
    def _parse_fix(self, fix: Any) -> _Fix:
        cfg = self.cfg
        try:
            flags = int(_get(fix, "flags"))
            fx = _Fix(
                t_us=int(_get(fix, "t_us")),
                lat_e7=int(_get(fix, "lat_e7")),
                lon_e7=int(_get(fix, "lon_e7")),
                alt_mm=int(_get(fix, "alt_mm")),
                vel=_finite3(_get(fix, "vel_ned_mps")),
                h_acc=_accuracy(_get(fix, "h_acc_m"), cfg.gps_pos_sigma_m),
                v_acc=_accuracy(_get(fix, "v_acc_m"), cfg.gps_alt_sigma_m),
                s_acc=_accuracy(_get(fix, "s_acc_mps"), cfg.gps_vel_sigma_mps),
                fix_type=int(_get(fix, "fix_type")),
                flags=flags,
            )
        except (TypeError, ValueError, KeyError, AttributeError, IndexError) as exc:
            raise BadArgError(f"not a GNSS fix: {exc}") from exc
        return fx

    def gps(self, fix: Any) -> None:
        """GPS step (ALGORITHMS.md 8). ``fix``: a GnssFix or a GNSS_DTYPE record.

        Step 1 raises BadArgError (fix_type < 2, an accuracy whose square is no finite float > 0),
        RangeError (position, a velocity component over 1000 m/s), NonFiniteError (a velocity
        flagged present but not finite), TimeBackwardsError, with the state unchanged (but for the
        pending observation of the last IMU step, completed first). A CS axis update that fails
        numerically (SingularError, NonFiniteError: a corrupted covariance) is raised after the
        fix's step 7 (GPS step 4; choice 22): the CS stays predicted to the fix, its other axes
        updated, and no attitude observation is made.
        """
        self._complete_pending()
        cfg = self.cfg
        fx = self._parse_fix(fix)
        has_ne = bool(fx.flags & GNSS_HAS_VEL_NE)
        has_d = bool(fx.flags & GNSS_HAS_VEL_D)
        has_alt = bool(fx.flags & GNSS_HAS_ALT)
        # Step 1: validation, nothing changes on error.
        if fx.fix_type < 2:
            raise BadArgError(f"fix_type {fx.fix_type} < 2")
        geo.check_geodetic(fx.lat_e7, fx.lon_e7, fx.alt_mm if has_alt else None)
        check_fix_velocity(fx.vel, (has_ne, has_ne, has_d))  # NONFINITE, then RANGE
        check_accuracies(h_acc_m=fx.h_acc, v_acc_m=fx.v_acc, s_acc_mps=fx.s_acc)  # used or not
        if self.t_lastfix_us is not None and fx.t_us <= self.t_lastfix_us:
            raise TimeBackwardsError(f"fix time {fx.t_us} <= {self.t_lastfix_us}")
        has_vel = (has_ne, has_ne, has_d)
        v0 = tuple(v if h else 0.0 for v, h in zip(fx.vel, has_vel, strict=True))

        # Step 2: first fix sets home.
        if self.home is None:
            home_alt = fx.alt_mm if has_alt else 0
            self._cs_restart(np.zeros(3), v0)
            self.home = (fx.lat_e7, fx.lon_e7, home_alt)
            if cfg.gravity_mps2 == 0.0:
                self.g = geo.normal_gravity_e7(fx.lat_e7, home_alt)
            self._remember_fix(fx, has_vel)
            return

        # Step 3: NED, CS predict (or re-initialise).
        lat0, lon0, alt0 = self.home
        ned = geo.ned_from_home(fx.lat_e7, fx.lon_e7, fx.alt_mm if has_alt else alt0, lat0, lon0, alt0)
        assert self.t_lastfix_us is not None
        T_us = fx.t_us - self.t_lastfix_us
        T = T_us * 1e-6
        if T_us > self._cs_dt_max_us:
            # Re-initialise instead (choice 17); steps 4-6 skipped. No increments carry the step
            # test's anchor over the gap: no fix held (n = 0).
            self._cs_restart(ned, v0)
            self.vst.n = 0
            self._step7_anchor(fx, has_ne, False, False, has_ne)
            self._remember_fix(fx, has_vel)
            return
        incs = self._aided_increments(fx.t_us, T)
        # Step 4 inputs: N, E position (+ velocity); D position with altitude on a 3-D fix, velocity.
        vel_mask = MASK_VEL if has_ne else 0
        d_mask = (MASK_POS if (has_alt and fx.fix_type >= 3) else 0) | (MASK_VEL if has_d else 0)
        masks = (MASK_POS | vel_mask, MASK_POS | vel_mask, d_mask)
        r_h = _white(fx.h_acc, self.cfg.gps_pos_white_m) ** 2
        r_p = (r_h, r_h, _white(fx.v_acc, self.cfg.gps_alt_white_m) ** 2)
        saved = copy.deepcopy((self.cs, self.vst, self.jumps, self.hold))
        p_0 = [float(ax.x[0]) for ax in self.cs.axes[:2]]  # N, E positions before the predict
        try:
            # Step 3's velocity step test (it may hold the fix; in fuzzy rows move the N, E detectors'
            # D), then the predict, plain or coasting, with the IMU-aided test priors.
            n_0 = self.vst.n  # fixes held before this one's test
            ran, held = self._velocity_step_test(fx, T, incs, has_ne)
            # after the test, in fuzzy rows: a held fix's position and velocity summed, p_last (choice 27)
            self._held_positions(fx, T, ned, held)
            self.cs.predict_aided(T, incs)
            # GPS step 4's jumps: against the predicted change on a fix the step test holds after the
            # hold's first (n > 1 now), whose velocity carries the fault
            rule = self._position_return(
                ned, T, r_h, p_0, fx.vel[:2] if has_ne else None, predicted=self.vst.n > 1
            )
            # GPS step 4's position hold (fuzzy rows, choice 28): its anchor carried on by the same d, but the
            # predicted change on every fix the step test holds and the fix after a held one (n > 0 before or
            # after the test), the hold or its release before the update (a held fix's position rows go out)
            v_ne = fx.vel[:2] if has_ne else None
            hf = self._position_hold(ned, T, r_h, p_0, v_ne, predicted=n_0 > 0 or self.vst.n > 0)
            # Step 4: CS update in the robust modes (ALGORITHMS.md 3, 5); its inputs were bounded at
            # step 1, so only an axis update failing numerically (SINGULAR, NONFINITE) is an error here.
            reports, failures = self.cs.update_robust_partial(
                z_p=ned,
                z_v=fx.vel,
                r_p=r_p,
                r_v=(fx.s_acc**2,) * 3,
                mask=masks,
                vel_held=held and self._step_test_rows(),  # the other modes: the hold changes no update
            )
        except McaError:
            self.cs, self.vst, self.jumps, self.hold = saved
            raise
        for ax in self.cs.axes[:2]:  # the caller's rows were this update's (a failed axis' too)
            ax.mem.caller_out = [False] * len(ax.mem.caller_out)
        # The reported T is the tested one (GPS step 3, section 5); an axis whose update failed reports
        # its last successful update's since the CS (re)started, NaN if none (choice 22).
        for i, rep in enumerate(reports):
            if rep is not None:
                self.gps_T[i] = rep.T
                self.cs_T_set[i] = True
            elif failures[i] is not None and not self.cs_T_set[i]:
                self.gps_T[i] = math.nan
        failure = next((err for err in failures if err is not None), None)
        # GPS step 3, the end of a fault the CS took in: a fix the step test judged the fault's end that
        # step 6 flags (from these step-4 updates, before any restart clears their marks) restarts the CS
        # from it, in every mode the test runs in (choice 23).
        # GPS step 4, the end of a position fault the CS took in: N or E returned (choice 24), the same
        # restart.
        vel_end = self.vst.ended and any(self._flags_end(i, reports[i], masks[i]) for i in (0, 1))
        # GPS step 4, the position hold's restart: a fix that steps back while not holding, or while holding
        # with *taken* set at its start (session 33), whose update of N or E left its position row out
        # (choice 28)
        pos_out = any(ax.mem.n_removed[0] > 0 for ax in self.cs.axes[:2])
        hold_end = hf.stepped_back and (not hf.was_holding or hf.was_taken) and pos_out
        restart = vel_end or rule.returned or hold_end
        # GPS step 6's flag of this fix (its N and E updates, read before any restart clears their marks)
        flagged = any(self._flags_fix(i, reports[i], masks[i]) for i in (0, 1))
        if restart:
            # either restart starts N and E at the position reference when both are near it (choice 25)
            self._cs_restart(ned, v0, from_ref=rule.near)
        elif self.aligned and rule.calm and not flagged and self.vst.n == 0:
            # a quiet fix: the position reference is the CS position after the update (choice 25)
            self.jumps.p_ref = np.array([float(ax.x[0]) for ax in self.cs.axes[:2]])
            self.jumps.ref = True
        if not restart:  # the position hold after the update: the onset, the anchor at this fix, or *taken*
            self._position_hold_after(hf, pos_out)
        if failure is not None or restart:
            # GPS step 4: the failed axes stay as predicted, the others updated; the CS was predicted
            # to the fix all the same, so step 7 is done (the next fix predicts from this one); steps
            # 5-6 are not (choice 22). The error is then raised. A restarted CS: steps 5-6 are not
            # done either, step 7 is (choices 23, 24). The history spacing is set before step 7 (choice 2).
            self._set_hist_spacing()
            self._step7(fx, has_vel, held, ran, reports)
            if failure is not None:
                raise failure
            return
        a_cs = tuple(float(ax.x[2]) for ax in self.cs.axes)
        if flagged:
            self.t_flag_us = fx.t_us
        # within tau_a (horizontal CS) of the last flagged fix, this one included: no roll/pitch
        rp_held = self.t_flag_us is not None and fx.t_us - self.t_flag_us < self._tau_a_us[0]

        # Step 5: compensation acceleration (and a_last, the lost-GPS decay's start, choice 5).
        self.a_last = a_cs  # type: ignore[assignment]
        usable = True
        if cfg.comp_mode == COMP_CS:
            a_n: tuple[float, float, float] = a_cs  # type: ignore[assignment]
            Pn, Pe = self.cs.axes[0].P[2, 2], self.cs.axes[1].P[2, 2]
            r_acc = float(Pn + Pe) / (2.0 * self.g**2)
        elif cfg.comp_mode == COMP_GPS_DIFF:
            dt_fix = T
            usable = fx.t_us - self.t_lastfix_us <= self._gps_timeout_us
            a_n = tuple(  # type: ignore[assignment]
                (v - vp) / dt_fix if (h and hp) else 0.0
                for v, vp, h, hp in zip(fx.vel, self.prev_vel, has_vel, self.prev_has_vel, strict=True)
            )
            r_acc = 2.0 * fx.s_acc**2 / (dt_fix**2 * self.g**2)
        else:
            a_n, r_acc = (0.0, 0.0, 0.0), 0.0
        if cfg.comp_mode in (COMP_CS, COMP_GPS_DIFF):
            # A yaw error d psi turns the horizontal compensation by d psi (body z as yaw axis).
            r_acc += (a_n[0] ** 2 + a_n[1] ** 2) * float(self.P[2, 2]) / self.g**2

        # Step 6: observations (none of a flagged fix's, no roll/pitch within tau_a of one, no course
        # from a held fix).
        if self.aligned:
            if not usable or rp_held:
                self._grav_skip()
            else:
                if cfg.comp_mode == COMP_CS:
                    entry = self.hist_lookup(fx.t_us - self._cs_lag_us)
                elif cfg.comp_mode == COMP_GPS_DIFF:
                    entry = self.hist_lookup(fx.t_us)
                else:
                    entry = self.hist[-1] if self.hist else None
                self._roll_pitch(entry, a_n, r_acc, None)
            # no course from a flagged fix, nor from one the velocity step test held (its velocity is
            # the suspect; in fuzzy rows a held fix is flagged anyway)
            if cfg.yaw_source == YAW_COG and has_ne and not flagged and not held:
                self._course_observation(fx)

        self._set_hist_spacing()  # after step 6, before step 7 (choice 2)
        self._step7(fx, has_vel, held, ran, reports)

    def _cs_restart(self, ned: np.ndarray, v0: tuple[float, ...], from_ref: bool = False) -> None:
        """A CS (re-)initialisation at the fix's position ``ned`` and velocity ``v0`` (GPS step 2 at home;
        step 3 after a gap longer than ``dt_max`` and at the end of a fault the CS took in; step 4 at the
        end of a position fault the CS took in, and at the position hold's restart): the axes start afresh
        (robust memories, coasting marks and priors cleared, choice 17), the compensation acceleration
        (``a_last``) is 0, and the N and E jump memory is cleared (``z_prev`` NaN, ``J = 0``, the position
        reference's *ref* clear), as is the position hold's (``s_p = 0``, *anchor*, *holding* and *taken*
        clear, choice 28, session 33). With
        ``from_ref`` (an end of a fault whose fix has *ref* set and both N and E near ``p_ref``, choice
        25) N and E start at ``p_ref`` with position variance ``sigma_p_m^2`` in place of ``p0_var_m2``;
        D, the velocities and the rest as at the fix. The velocity step test's ``n`` is left as it is
        (the caller of the gap's re-initialisation sets ``n = 0``; at home it is 0 already)."""
        p0 = np.array(ned, dtype=np.float64)
        if from_ref:
            p0[:2] = self.jumps.p_ref
        self.cs.init(p0, v0)
        if from_ref:
            for ax in self.cs.axes[:2]:
                ax.P[0, 0] = ax.cfg.sigma_p_m**2
        self.cs_T_set = [False, False, False]
        self.a_last = (0.0, 0.0, 0.0)
        self.jumps = _PosJumps()
        self.hold = _PosHold()

    def _position_return(
        self,
        ned: np.ndarray,
        T: float,
        r_p: float,
        p_0: list[float],
        v_ne: tuple[float, ...] | None,
        predicted: bool,
    ) -> _PosRule:
        """ALGORITHMS.md 8, GPS step 4, "The end of a position fault the CS took in" (choice 24): on N and
        E, after the predict and before the update, an axis whose robust mode is neither plain nor fuzzy
        rows sums the fix's position jumps the fixes' velocities do not explain, ``j = (z - z_prev) - d``
        with ``d = T (v + v_prev) / 2`` (the trapezoid of this fix's N (E) velocity ``v_ne`` and the last
        fix's, ``prev_vel`` of step 7) and, when either fix has no N/E velocity (``v_ne`` None, or the
        last fix's mask clear) or ``predicted`` is set (a fix the velocity step test holds after the
        hold's first, ``n > 1`` after step 3: its velocity carries the fault), ``d = p - p_0`` (the
        predicted change), past ``min(2 chi2_1(1e-4) R, B / 4)`` (``R`` = ``r_p``, the position variance
        after the receiver model; ``B`` the material bound below) into ``J``, decays ``J`` by ``T / (5
        tau_p)`` and keeps ``z_prev = z``; the jump is counted and may return on every fix alike (the
        hold's first fix, ``n = 1``, takes the velocities' ``d``). The axis *returns* when
        this fix's ``j`` was a jump (summed into ``J`` on this fix) or the jumps summed are within half
        the material bound on both N and E (``4 J^2 <= B`` of each axis, its own ``J`` and ``B``: no
        position fault pending on either), and the innovation ``nu = z - (p + eps_p)`` is material,
        ``nu^2 > B = chi2_1(1e-4) (sigma_p^2 + R)``, and ``4 J^2 <= nu^2`` (the axis' own; ``J`` after
        this fix's jump and forgetting).
        The position reference (choice 25), aligned only: when *ref* is set, ``p_ref += d`` (this fix's
        ``d``, after ``J``'s update) and the axis is *near* when ``(z - p_ref)^2 <= B``.
        Returns whether N or E returned (the caller restarts the CS after step 4), whether *ref* is set
        and both N and E are near, and whether the rule ran on N and E with neither jumped nor a fault
        pending (``4 J^2 > B``, this fix's ``J``). The axes of other modes leave ``z_prev``, ``J``,
        ``p_ref`` and *ref* as they are."""
        k = chi2_quantile(POS_RETURN_LEVEL, 1)
        mem = self.jumps
        use_ref = self.aligned and mem.ref
        near = use_ref
        calm = True
        ran = 0
        motion = self._fix_motion(T, p_0, v_ne, predicted)
        # per axis: this fix's j was a jump, a position fault is pending, and the CS is materially off
        # the fix with J within half of that (nu^2 > B and 4 J^2 <= nu^2)
        jumped_ax: list[bool] = []
        pending_ax: list[bool] = []
        off_ax: list[bool] = []
        for i, ax in enumerate(self.cs.axes[:2]):
            rc, c = ax.cfg.robust, ax.cfg
            if rc.mode == "plain" or (rc.mode == "fuzzy" and rc.fuzzy_reject == FUZZY_ROWS):
                continue
            z, p = float(ned[i]), float(ax.x[0])
            material = k * (c.sigma_p_m**2 + r_p)  # beyond what the receiver's own wandering explains
            d = float(motion[i])
            j = (z - mem.z_prev[i]) - d  # NaN after a (re-)initialisation: no jump
            # beyond two fixes' white error; a quarter of the material bound always is a jump
            jumped = not math.isnan(j) and j * j > min(2.0 * k * r_p, material / 4.0)
            if jumped:
                mem.J[i] += j
            mem.J[i] -= mem.J[i] * T / (POS_JUMP_FORGET * c.tau_p_s)
            mem.z_prev[i] = z
            if use_ref:  # the reference carried on by the same d; near: within the material bound
                mem.p_ref[i] += d
                near = near and (z - mem.p_ref[i]) ** 2 <= material
            nu = z - (p + float(ax.x[3]))
            pending = 4.0 * mem.J[i] ** 2 > material  # J beyond half the material bound
            jumped_ax.append(jumped)
            pending_ax.append(pending)
            off_ax.append(nu * nu > material and 4.0 * mem.J[i] ** 2 <= nu * nu)
            calm = calm and not jumped and not pending
            ran += 1
        # an axis that jumped, or any axis when no position fault is pending on either N or E (each its
        # own J and B: the restart re-initialises both), returns when the CS is materially off its fix
        none_pending = not any(pending_ax)
        returned = any((jmp or none_pending) and off for jmp, off in zip(jumped_ax, off_ax, strict=True))
        return _PosRule(returned, near and ran == 2, calm and ran == 2)

    def _fix_motion(
        self, T: float, p_0: list[float], v_ne: tuple[float, ...] | None, predicted: bool
    ) -> np.ndarray:
        """GPS step 4's ``d`` of N and E, what the position return rule and the position hold carry the
        fixes on by: the trapezoid ``T (v + v_prev) / 2`` of this fix's N, E velocity ``v_ne`` and the last
        fix's (step 7 remembered it), or the CS's predicted change ``p - p_0`` when either fix has no N/E
        velocity or ``predicted`` (the held velocity carries the fault: for the position return rule a fix
        the velocity step test holds after the hold's first, for the position hold any fix it holds and the
        fix after a held one)."""
        v_prev = self.prev_vel[:2] if self.prev_has_vel[0] else None
        if not predicted and v_ne is not None and v_prev is not None:
            return T * (np.array(v_ne[:2], dtype=np.float64) + np.array(v_prev, dtype=np.float64)) / 2.0
        return np.array([float(ax.x[0]) - p_0[i] for i, ax in enumerate(self.cs.axes[:2])])

    def _position_hold(
        self,
        ned: np.ndarray,
        T: float,
        w2: float,
        p_0: list[float],
        v_ne: tuple[float, ...] | None,
        predicted: bool,
    ) -> _HoldFix:
        """ALGORITHMS.md 8, GPS step 4, "The position hold" (session 28, choice 28), before the update: in
        fuzzy rows, on N and E, after step 3's predict and the step test's sums (which read ``z_prev`` as
        ``p_last``), with ``d`` the position rule's (the trapezoid of this fix's and the last fix's N, E
        velocities, or the predicted change ``p - p_0`` without them or when ``predicted``: ``n > 0`` before
        or after step 3's test, a fix the step test holds, its first included, or the fix after a held one)
        and ``dz = z - z_prev``: ``z_prev = z``; when aligned and
        *anchor*, ``p_a += d``, ``e = z - p_a``, ``r = dz - d``. With ``t' = t_h + T`` while *holding* (``T``
        otherwise) and ``V = 2 (w^2 + sigma_p^2 t' / tau_p)`` (``w2`` this fix's N/E position variance
        after the receiver model; ``sigma_p``, ``tau_p`` of ``cs_h``), the fix *steps back* when ``r . s_p <
        0``, ``(r . s_p)^2 >= 0.5 |r|^2 |s_p|^2`` and ``| |r|^2 - 1.25 |s_p|^2 | <= |s_p|^2`` (aligned,
        *anchor*, ``s_p != 0`` and ``z_prev`` not NaN). Aligned, *anchor* and *holding*: ``t_h = t'``, and
        the fix stays held when it does not step back, ``2 e . s_p >= |s_p|^2``, ``|e - s_p|^2 <= g4 V``
        and either N's position row was left out by fewer than ``reject_reset_n`` updates in a row (N's
        memory before the update) or ``(e . s_p)^2 > g2 |s_p|^2 V``: N's and E's position rows then go out
        of their updates (the memories' ``caller_out``, the N/E pair's rows) and their detectors take ``D =
        max(D, 2)``; otherwise the hold ends (*holding*, *anchor* and *taken* clear, ``s_p`` kept) and, when
        the step test holds nothing (``n = 0`` after step 3), ``D = min(D, 1)``. Returns what the part after
        the update needs; a mode other than fuzzy rows changes nothing (``ran`` False)."""
        if not self._step_test_rows():
            return _HoldFix(False, False, False, False, np.zeros(2), 0.0)
        h, cfg_h = self.hold, self.cfg.cs_h
        n_ax, e_ax = self.cs.axes[0], self.cs.axes[1]
        z = np.array([float(ned[0]), float(ned[1])])
        d = self._fix_motion(T, p_0, v_ne, predicted)
        dz = z - self.jumps.z_prev  # NaN after a CS (re-)initialisation
        self.jumps.z_prev = z.copy()
        was_holding, was_taken = h.holding, h.taken
        active = self.aligned and h.anchor
        e = r = np.zeros(2)
        if active:
            h.p_a = h.p_a + d
            e = z - h.p_a
            r = dz - d  # this fix's jump
        t1 = h.t_h + T if h.holding else T
        V = 2.0 * (w2 + cfg_h.sigma_p_m**2 * t1 / cfg_h.tau_p_s)  # the receiver's position error over t'
        sp2 = float(h.s_p @ h.s_p)
        stepped_back = False
        if active and sp2 > 0.0 and bool(np.all(np.isfinite(dz))):
            rs, rr = float(r @ h.s_p), float(r @ r)
            stepped_back = rs < 0.0 and rs * rs >= 0.5 * rr * sp2 and abs(rr - 1.25 * sp2) <= sp2
        if active and h.holding:
            h.t_h = t1
            es = float(e @ h.s_p)
            de = e - h.s_p
            # the guard: N's position row out by fewer than cs_h's whole-update guard of updates in a row
            guard_open = n_ax.mem.n_removed[0] < cfg_h.robust.reject_reset_n
            significant = es * es > chi2_quantile(HOLD_LEVEL_STEP, 2) * sp2 * V  # beyond the wander
            stays = (
                not stepped_back
                and 2.0 * es >= sp2  # nearer the held step than the anchor
                and float(de @ de) <= chi2_quantile(HOLD_LEVEL_WANDER, 2) * V  # still the held step
                and (guard_open or significant)
            )
            if stays:  # held: the position rows out with the pair's, and the alarm
                for ax in (n_ax, e_ax):
                    ax.mem.caller_out[0] = True
                    ax.mem.d_k = max(ax.mem.d_k, HOLD_D_HELD)
            else:  # the hold ends (*taken* with it, session 33); s_p stays (the step may still be in)
                h.holding = h.anchor = h.taken = False
                if self.vst.n == 0:
                    for ax in (n_ax, e_ax):
                        ax.mem.d_k = min(ax.mem.d_k, HOLD_D_RELEASE)
        return _HoldFix(True, stepped_back, was_holding, was_taken, z, V)

    def _position_hold_after(self, hf: _HoldFix, pos_out: bool) -> None:
        """ALGORITHMS.md 8, GPS step 4, the position hold after the update (choice 28), on a fix the CS did
        not restart on. *Holding* (after the decision), with the updates of N and E both keeping their
        position rows in (``pos_out`` False: ``n_removed`` of the position row 0 on both after the update;
        only section 5's whole-update guard does that to a held fix): *taken* is set and the hold goes on
        (session 33). Aligned and not *holding*: a fix that steps back sets ``s_p = 0``; then, with ``j =
        z - p_a``, when *anchor* is set, ``pos_out`` (the update of N or E left its position row out: the
        memory's ``n_removed`` of the position row > 0 after it), ``|j|^2 > g4 V`` and the fix did not step
        back, the hold starts (*holding*, ``s_p = j``, ``t_h = 0``); otherwise ``p_a = z`` and *anchor*."""
        h = self.hold
        if not hf.ran:
            return
        if h.holding:  # the held step went into the CS: its end (a step back) restarts it
            if not pos_out:
                h.taken = True
            return
        if not self.aligned:
            return
        if hf.stepped_back:
            h.s_p = np.zeros(2)
        j = hf.z - h.p_a
        onset = (
            h.anchor
            and pos_out
            and float(j @ j) > chi2_quantile(HOLD_LEVEL_WANDER, 2) * hf.V
            and not hf.stepped_back
        )
        if onset:
            h.holding, h.s_p, h.t_h = True, j, 0.0
        else:
            h.p_a, h.anchor = hf.z.copy(), True

    def _step7(
        self,
        fx: _Fix,
        has_vel: tuple[bool, bool, bool],
        held: bool,
        ran: bool,
        reports: list[RobustReport | None],
    ) -> None:
        """GPS step 7 after a CS update, whole or with failed axes: t_lastfix = t_cs = t_fix, the fix
        velocity remembered, the step test's anchor (the N and E updates applied their velocity: both
        made, neither marked out; choice 22)."""
        has_ne = has_vel[0]
        made = reports[0] is not None and reports[1] is not None
        applied_v = has_ne and made and not (self.cs.axes[0].out or self.cs.axes[1].out)
        self._step7_anchor(fx, has_ne, held, ran, ran or applied_v)
        self._remember_fix(fx, has_vel)

    def _flags_fix(self, axis: int, rep: RobustReport | None, mask: int) -> bool:
        """GPS step 6: the robust mode of a horizontal axis' update flagged the fix."""
        if rep is None:
            return False
        rc = self.cs.axes[axis].cfg.robust
        if rc.mode == "plain":
            return False
        if rc.mode == "igg3":  # the velocity row removed (weight 0), or the update rejected
            return bool(rep.rejected) or bool(mask & MASK_VEL and float(rep.w[rep.m - 1]) == 0.0)
        if rc.mode == "fuzzy" and rc.fuzzy_reject == FUZZY_ROWS:  # the axis coasts after the update
            return bool(self.cs.axes[axis].out)
        return bool(rep.detected) or rep.T > chi2_quantile(FLAG_LEVEL, rep.m)

    def _flags_end(self, axis: int, rep: RobustReport | None, mask: int) -> bool:
        """GPS step 3, the end of a fault the CS took in: step 6's flag of this fix by a horizontal axis'
        update (choice 23). In fuzzy rows and IGG-III it is the axis' coasting mark after step 4 (the
        update left its velocity row out or was rejected; an axis whose update failed numerically keeps
        the mark it had), in FTA, AKF and fuzzy reject or inflate the mode's detection or its tested
        ``T`` over ``chi2_m(0.01)`` (:meth:`_flags_fix`; a failed update flags nothing)."""
        rc = self.cs.axes[axis].cfg.robust
        if rc.mode == "igg3" or (rc.mode == "fuzzy" and rc.fuzzy_reject == FUZZY_ROWS):
            return bool(self.cs.axes[axis].out)
        return self._flags_fix(axis, rep, mask)

    def _velocity_step_test(
        self, fx: _Fix, T: float, incs: list[AxisInc | None], has_ne: bool
    ) -> tuple[bool, bool]:
        """The velocity step test of GPS step 3 (ALGORITHMS.md 8): (the test ran, the fix is held).
        It runs in every robust mode of ``cs_h`` but plain (choice 20). In fuzzy rows a held fix
        leaves the N and E velocity rows out (Cs3.update_robust's ``vel_held``, passed by the caller)
        and raises both detectors' D to at least 2, and the return, or the first fix after a hold, not
        armed, lowers them to at most 1; in the other modes a hold changes no update and no D (its only
        effect is the course observation the held fix does not give, GPS step 6). In every mode that
        disarmed release is the fault's end (``vst.ended``: the CS restarts from it when step 6 then
        flags the fix, choice 23). In fuzzy rows a fix also fails while holding when the held fixes'
        positions say the held step (``vst.e``, ``vst.t_e``; ``w`` the white part of this fix's ``h_acc``,
        GPS step 4's receiver model), and such a fix's return needs no upper bound on its size; when they
        agree with the fixes' velocities and not with the held step, they release it (it fails by no
        rule), disarmed and no fault's end (choice 27). ``C`` and ``C_r`` are scaled by ``vst.lam``, read
        here and updated after the test from this fix's ``|s|^2`` and ``C_u`` when no fix was held at its
        start and it passes on its own (choice 20, session 31)."""
        st = self.vst
        st.ended = False
        cfg_h = self.cfg.cs_h
        n_ax, e_ax = self.cs.axes[0], self.cs.axes[1]
        inc_n, inc_e = incs[0], incs[1]
        rows_mode = self._step_test_rows()
        if not (
            cfg_h.robust.mode != "plain" and inc_n is not None and inc_e is not None and has_ne and st.anchor
        ):
            st.n = 0
            return False, False
        dv = np.array([inc_n.dv, inc_e.dv])
        qa, qc = inc_n.qa, inc_n.qc  # the same on N and E
        v_fix = np.array(fx.vel[:2])
        v_last = np.array(self.prev_vel[:2])
        v_p = st.v_a + dv
        s = v_fix - v_p
        r = v_fix - v_last - dv
        s_acc2 = fx.s_acc**2
        # the variance scale, read before the test (ALGORITHMS.md 8 GPS step 3, session 31): every
        # comparison with k C or C_r uses the scaled ones; the positions' V_e does not scale
        lam = st.lam
        C_u = s_acc2 + st.V_a + qa * T * T
        C = lam * C_u
        C_r = lam * (2.0 * s_acc2 + qa * T * T)
        k = chi2_quantile(STEP_LEVEL_FAIL if st.n == 0 else STEP_LEVEL_HELD, 2)
        ss, rr = float(s @ s), float(r @ r)
        holding = st.n > 0
        s0n = float(st.s0 @ st.s0)
        # fuzzy rows, while holding: the held fixes' positions say the held step (the mean velocity by
        # which they disagree, e / t_e, nearer s0 than 0, and e . s0 beyond the receiver's position
        # error over the hold: its white part at both ends, its Gauss-Markov part's wander), choice 27;
        # or they release the fix: e . s0 within that error of 0 and beyond it from the step (t_e |s0|^2)
        positions = released = False
        if rows_mode and holding:
            es0 = float(st.e @ st.s0)
            w2 = _white(fx.h_acc, self.cfg.gps_pos_white_m) ** 2  # this fix's N/E position variance
            V_e = 2.0 * w2 + 2.0 * cfg_h.sigma_p_m**2 * st.t_e / cfg_h.tau_p_s
            positions = 2.0 * es0 >= st.t_e * s0n and es0 * es0 > k * s0n * V_e
            off, k_fail = st.t_e * s0n - es0, chi2_quantile(STEP_LEVEL_FAIL, 2)
            released = es0 * es0 <= k * s0n * V_e and off * off > k_fail * s0n * V_e
        if holding:  # still failing, nearer the held step than the anchor, or the positions say it;
            # released by the positions, it does not fail whatever the anchor says
            fails = not released and (ss > k * C or 2.0 * float(s @ st.s0) >= s0n or positions)
        else:  # a step, unless it agrees with the anchor before (the anchor was the spike)
            d_pre = v_fix - (st.v_pre + dv)
            fails = ss > k * C and not (st.pre and float(d_pre @ d_pre) <= k * C)
        u, q = (r, rr) if holding else (s, ss)
        us0 = float(u @ st.s0)
        # the size window (ALGORITHMS.md 8 GPS step 3): q >= 0.5 |s0|^2 always (with C_r scaled, a raw
        # step half the held one's size inside a burst passed for its end, session 31); q <= 2.25 |s0|^2
        # unless the positions say the held step (s0 may be off the fault)
        sized = q >= 0.5 * s0n and (positions or q <= 2.25 * s0n)
        reverse = us0 < 0.0 and us0 * us0 >= 0.5 * q * s0n and sized
        stepped_back = rr > chi2_quantile(STEP_LEVEL_FAIL, 2) * C_r
        is_return = fails and reverse and (stepped_back if holding else st.armed)
        # The guard (with n before this fix): fuzzy rows' whole-update guard, reject_reset_n fixes; the
        # other modes n T < 20 s, T this fix's interval, compared in integer us (ALGORITHMS.md 8, Times)
        if rows_mode:
            guard_open = st.n < cfg_h.robust.reject_reset_n
        else:
            guard_open = st.n * int(round(T * 1e6)) < STEP_HOLD_MAX_US
        if fails and not is_return and guard_open:
            if st.n == 0:
                st.s0 = s
                st.armed = False
            st.v_a = v_p
            st.V_a += qc * T * T
            st.n += 1
            if rows_mode:  # the alarm: the velocity rows go out at step 4 (vel_held)
                for ax in (n_ax, e_ax):
                    ax.mem.d_k = max(ax.mem.d_k, 2.0)
            return True, True
        if is_return or holding:
            st.armed = not (is_return or released) and rr <= k * C_r
            if not st.armed:
                st.ended = not released  # a release by the positions is no fault's end: no restart
                if rows_mode:  # the alarm releases at the first clean fix
                    for ax in (n_ax, e_ax):
                        ax.mem.d_k = min(ax.mem.d_k, 1.0)
        # after the test, with no fix held at its start and the fix passing on its own (not by the
        # anchor before; a held fix returned above): the scale follows the mean of |s|^2 / (2 C_u)
        # (ALGORITHMS.md 8 GPS step 3, session 31), in float64
        if not holding and ss <= k * C:
            st.lam = min(1.0, max(1.0 / 4.0, (31.0 / 32.0) * lam + ss / (64.0 * C_u)))
        st.n = 0
        st.v_pre = v_p  # every fix not held
        return True, False

    def _held_positions(self, fx: _Fix, T: float, ned: np.ndarray, held: bool) -> None:
        """After the velocity step test, in fuzzy rows (choice 27), a fix the test held (``h = n > 0``
        after it): the hold's first (``h = 1``) sets ``vst.e = 0``, ``vst.t_e = 0`` and adds nothing; each
        one after it (``h > 1``) adds ``T (v_fix + v_last) / 2 - (p_fix - p_last)`` to ``vst.e`` and ``T``
        to ``vst.t_e``. A fix not held changes neither. ``p_last`` is GPS step 4's memory of the last
        position, ``jumps.z_prev``, which the position hold sets to this fix's N and E position (step 3's
        ``ned``) after these sums on every fix (choice 28: a held fix's "sets ``p_last``"); ``v_last`` the
        last fix's velocity (step 7's ``prev_vel``). On ``h > 1`` both are the held fix before's (it had N
        and E velocity: a held fix has), but ``p_last`` is NaN when that fix restarted the CS (the position
        hold's restart): the NaN propagates into ``vst.e`` for the rest of the hold (choice 27)."""
        if not (held and self._step_test_rows()):
            return
        st = self.vst
        p_fix = np.array([float(ned[0]), float(ned[1])])
        if st.n == 1:
            st.e, st.t_e = np.zeros(2), 0.0
        else:
            v_fix, v_last = np.array(fx.vel[:2]), np.array(self.prev_vel[:2])
            st.e = st.e + (T * (v_fix + v_last) / 2.0 - (p_fix - self.jumps.z_prev))
            st.t_e += T

    def _step_test_rows(self) -> bool:
        """The horizontal CS configuration is fuzzy rows (``fuzzy`` with ``fuzzy_reject`` 2): the velocity
        step test's hold leaves the N and E velocity rows out and raises the alarm (GPS step 3)."""
        rc = self.cfg.cs_h.robust
        return rc.mode == "fuzzy" and rc.fuzzy_reject == FUZZY_ROWS

    def _step7_anchor(self, fx: _Fix, has_ne: bool, held: bool, ran: bool, ok: bool) -> None:
        """GPS step 7 for the velocity step test: when aligned and unless the fix was held, its N, E
        velocity is the anchor, with variance s_acc^2, when it has one and ``ok`` (the test ran on it,
        or both N and E applied their velocity); *pre* is whether the test ran on it."""
        if held or not self.aligned:
            return
        st = self.vst
        st.v_a = np.array(fx.vel[:2])
        st.V_a = fx.s_acc**2
        st.pre = ran
        st.anchor = has_ne and ok

    def _imu_increments(self, t0: int, t1: int) -> tuple[np.ndarray, np.ndarray] | None:
        """Velocity and position increments (dv = int a, dp = int int a) over (t0, t1] from the
        history ring, a = C_nb(q) f + [0, 0, g] per entry (ALGORITHMS.md 8, GPS step 3); None when
        the ring does not cover the interval, reaches more than 2 dt_h past the newest entry (whose
        a is held up to there; session 33, one dt_h before) or a saturated entry is used."""
        h = list(self.hist)
        if len(h) < 2 or h[0].t_us > t0:
            return None
        dp, dv = np.zeros(3), np.zeros(3)

        def add(e: HistEntry, o_us: int) -> None:
            nonlocal dp, dv
            a = att.dcm_from_quat(e.q) @ np.array(e.f_b) + np.array([0.0, 0.0, self.g])
            o = o_us * 1e-6
            dp = dp + dv * o + 0.5 * a * o * o
            dv = dv + a * o

        for prev, e in zip(h[:-1], h[1:], strict=True):
            lo, hi = max(prev.t_us, t0), min(e.t_us, t1)
            if hi <= lo:
                continue
            if e.saturated:
                return None
            add(e, hi - lo)
        last = h[-1]
        if t1 > last.t_us:
            # Held for at most twice the spacing (ALGORITHMS.md 8, GPS step 3, session 33; choice 14).
            if t1 - last.t_us > 2 * self.hist_dt_us or last.saturated:
                return None
            add(last, t1 - last.t_us)
        return dp, dv

    def _aided_increments(self, t_fix: int, T: float) -> list[AxisInc | None]:
        """Per CS axis the IMU increments and error variances of this fix's predict, or None
        (ALGORITHMS.md 8, GPS step 3; N and E once any yaw observation was made, choice 15)."""
        cfg = self.cfg
        none: list[AxisInc | None] = [None, None, None]
        if not (cfg.gps_test_imu and self.aligned) or self.t_lastfix_us is None:
            return none
        inc = self._imu_increments(self.t_lastfix_us, t_fix)
        if inc is None:
            return none
        dp, dv = inc
        ah2 = (dv[0] ** 2 + dv[1] ** 2) / T**2
        att_h = self.g**2 * (self.P[0, 0] + self.P[1, 1]) + ah2 * self.P[2, 2]
        qa_v, qc_v = cfg.imu_acc_sigma_mps2**2, cfg.coast_acc_sigma_mps2**2
        qa_h, qc_h = qa_v + att_h, qc_v + att_h
        # N and E: once any yaw observation was made (however long ago; its growing variance is in
        # qa), and while qa + qc is finite
        aid_h = self.t_yaw_us is not None and math.isfinite(qa_h + qc_h)
        out: list[AxisInc | None] = [
            AxisInc(float(dp[i]), float(dv[i]), float(qa_h), float(qc_h)) if aid_h else None for i in (0, 1)
        ]
        out.append(AxisInc(float(dp[2]), float(dv[2]), qa_v, qc_v))
        return out

    def _remember_fix(self, fx: _Fix, has_vel: tuple[bool, bool, bool]) -> None:
        self.t_lastfix_us = fx.t_us
        self.prev_vel = fx.vel
        self.prev_has_vel = has_vel

    def _course_observation(self, fx: _Fix) -> None:
        """Course over ground (ALGORITHMS.md 7), observation time t_fix (choice 6), through the course
        gate when the attitude filter's robust mode is not plain, and its guard (choice 26)."""
        cfg = self.cfg
        vn, ve = fx.vel[0], fx.vel[1]
        speed = math.hypot(vn, ve)
        if speed < cfg.cog_min_speed_mps:
            return
        entry = self.hist_lookup(fx.t_us)
        if entry is None:
            return
        # made: counted in n_cog unless taken
        psi_m = math.atan2(ve, vn)
        sigma2 = cfg.cog_sigma0_rad**2 + (fx.s_acc / speed) ** 2
        # the guard: 10 in a row not taken, and no yaw observation taken for more than 30 s of IMU
        # time with no velocity fault released still in (the step test not armed), or, armed or not,
        # for more than 120 s: a yaw alignment
        realign = (
            self.yaw_aligned
            and self.n_cog >= COG_MISSED_MAX
            and self.t_yaw_us is not None
            and self.t_imu_us is not None
            and (
                (not self.vst.armed and self.t_imu_us - self.t_yaw_us > COG_GUARD_US)
                or self.t_imu_us - self.t_yaw_us > COG_GUARD_ARMED_US
            )
        )
        gate = cfg.att.robust.mode != "plain"
        taken = self._yaw(psi_m, sigma2, entry.q, gate=gate, realign=realign)
        self.n_cog = 0 if taken else min(self.n_cog + 1, COG_MISSED_MAX)

    # ----------------------------------------------------------------------------------
    # Magnetometer step
    # ----------------------------------------------------------------------------------
    def mag(self, t_us: int, mag_b: Any) -> None:
        """Magnetometer step (ALGORITHMS.md 8). Raises NonFiniteError."""
        self._complete_pending()
        m = _finite3(mag_b)
        if not all(math.isfinite(v) for v in m):
            raise NonFiniteError("magnetometer sample not finite")
        cfg = self.cfg
        if cfg.yaw_source != YAW_MAG or not self.aligned:
            return
        t_us = int(t_us)
        if self.t_mag_us is not None and t_us - self.t_mag_us < self._grav_period_us:
            return
        if m[0] == 0.0 and m[1] == 0.0 and m[2] == 0.0:
            return
        self.t_mag_us = t_us
        psi_m = att.mag_heading(self.q, np.array(m), cfg.mag_declination_rad)
        self._yaw(psi_m, cfg.mag_yaw_sigma_rad**2, self.q)

    # ----------------------------------------------------------------------------------
    # Output
    # ----------------------------------------------------------------------------------
    def flags(self) -> int:
        f = 0
        if self.aligned:
            f |= FLAG_ALIGNED
        if self.home is not None:
            f |= FLAG_HOME_SET
        if self.t_imu_us is None or self._gps_lost(self.t_imu_us):
            f |= FLAG_GPS_LOST
        if (
            self.cfg.yaw_source == YAW_NONE
            or self.t_yaw_us is None
            or self.t_imu_us is None
            or self.t_imu_us - self.t_yaw_us > YAW_UNOBSERVED_US
        ):
            f |= FLAG_YAW_UNOBSERVED
        if self.grav_skipped:
            f |= FLAG_GRAV_SKIPPED
        if self.saturated_seen:
            f |= FLAG_SATURATED
        if self.hist_miss:
            f |= FLAG_HIST_MISS
        for i, ax in enumerate(self.cs.axes):  # each CS axis' alarm after the last fix
            if ax.mem.alarm:
                f |= FLAG_ALARM_N << i
        return f

    def _cs_extrapolated(self) -> tuple[list[float], list[float], list[float]]:
        """CS mean carried to the newest IMU time with constant acceleration."""
        if self.t_lastfix_us is None or self.t_imu_us is None:
            tau = 0.0
        else:
            tau = (self.t_imu_us - self.t_lastfix_us) * 1e-6
        pos, vel, acc = [], [], []
        for ax in self.cs.axes:
            p, v, a = float(ax.x[0]), float(ax.x[1]), float(ax.x[2])
            pos.append(p + v * tau + 0.5 * a * tau * tau)
            vel.append(v + a * tau)
            acc.append(a)
        return pos, vel, acc

    def output(self) -> NavOutput:
        """The output record (ALGORITHMS.md 8, output)."""
        pos, vel, acc = self._cs_extrapolated()
        return NavOutput(
            t_us=-1 if self.t_imu_us is None else self.t_imu_us,
            q=np.array(self.q),
            euler=np.array(att.euler_from_quat(self.q)),
            gyro_bias=np.array(self.b),
            pos_ned=np.array(pos),
            vel_ned=np.array(vel),
            acc_ned=np.array(acc),
            att_P_diag=np.diag(self.P).copy(),
            cs_P_diag=np.concatenate([np.diag(ax.P)[:3] for ax in self.cs.axes]),
            rp_T=self.rp_T,
            gps_T=np.array(self.gps_T),
            flags=self.flags(),
            n_grav_made=self.n_grav_made,
            n_grav_skipped=self.n_grav_skipped,
            n_yaw_made=self.n_yaw_made,
        )

    def copy(self) -> Nav:
        """A deep copy (independent state)."""
        return copy.deepcopy(self)


# --------------------------------------------------------------------------------------
# Batch replay (ALGORITHMS.md 9)
# --------------------------------------------------------------------------------------

_KIND_IMU, _KIND_GPS, _KIND_MAG = 0, 1, 2


def replay_order(recording: Recording) -> tuple[np.ndarray, np.ndarray]:
    """(kind, index) of every event in replay order: by time (IMU t_us, fix t_rx_us, mag t_us);
    at equal times IMU, GPS, magnetometer; within a kind, recording order."""
    imu, gnss, mag = recording.imu, recording.gnss, recording.mag
    mag = np.zeros(0, dtype=[("t_us", np.int64)]) if mag is None else mag
    t = np.concatenate(
        [imu["t_us"].astype(np.int64), gnss["t_rx_us"].astype(np.int64), mag["t_us"].astype(np.int64)]
    )
    kind = np.concatenate(
        [np.full(len(imu), _KIND_IMU), np.full(len(gnss), _KIND_GPS), np.full(len(mag), _KIND_MAG)]
    )
    idx = np.concatenate([np.arange(len(imu)), np.arange(len(gnss)), np.arange(len(mag))])
    order = np.lexsort((idx, kind, t))
    return kind[order], idx[order]


def run(recording: Recording, cfg: NavConfig | None = None) -> dict[str, np.ndarray]:
    """Replay a recording through a fresh :class:`Nav` (ALGORITHMS.md 9).

    Returns a dict of arrays, one row per IMU sample (recorded after its step, whatever its
    status): ``t_us``, ``q`` (n, 4), ``euler`` (n, 3: roll, pitch, yaw), ``gyro_bias``,
    ``pos_ned``, ``vel_ned``, ``acc_ned`` (n, 3), ``att_P_diag`` (n, 6), ``cs_P_diag`` (n, 9:
    N(p, v, a), E(p, v, a), D(p, v, a)), ``rp_T`` (n,), ``gps_T`` (n, 3), ``flags`` (n,
    uint32), ``n_grav_made``, ``n_grav_skipped``, ``n_yaw_made`` (n,); and the per-event
    status codes ``imu_status`` (n,), ``gps_status`` (n_fix,), ``mag_status`` (n_mag,)
    (0 OK, otherwise STATUS_CODES).
    """
    nav = Nav(cfg)
    imu, gnss = recording.imu, recording.gnss
    mag = recording.mag if recording.mag is not None else np.zeros(0, dtype=[("t_us", np.int64)])
    n = len(imu)
    out: dict[str, np.ndarray] = {
        "t_us": np.zeros(n, np.int64),
        "q": np.zeros((n, 4)),
        "euler": np.zeros((n, 3)),
        "gyro_bias": np.zeros((n, 3)),
        "pos_ned": np.zeros((n, 3)),
        "vel_ned": np.zeros((n, 3)),
        "acc_ned": np.zeros((n, 3)),
        "att_P_diag": np.zeros((n, 6)),
        "cs_P_diag": np.zeros((n, 9)),
        "rp_T": np.zeros(n),
        "gps_T": np.zeros((n, 3)),
        "flags": np.zeros(n, np.uint32),
        "n_grav_made": np.zeros(n, np.int64),
        "n_grav_skipped": np.zeros(n, np.int64),
        "n_yaw_made": np.zeros(n, np.int64),
        "imu_status": np.zeros(n, np.int32),
        "gps_status": np.zeros(len(gnss), np.int32),
        "mag_status": np.zeros(len(mag), np.int32),
    }
    kinds, idxs = replay_order(recording)
    imu_t = imu["t_us"].tolist()
    imu_w = imu["gyro_rps"].tolist()
    imu_f = imu["accel_mps2"].tolist()
    mag_t = mag["t_us"].tolist() if len(mag) else []
    mag_m = mag["mag_b"].tolist() if len(mag) else []
    o_t, o_q, o_eul, o_b = out["t_us"], out["q"], out["euler"], out["gyro_bias"]
    o_p, o_v, o_a = out["pos_ned"], out["vel_ned"], out["acc_ned"]
    o_Pa, o_Pc, o_rpT, o_gT = out["att_P_diag"], out["cs_P_diag"], out["rp_T"], out["gps_T"]
    o_fl, o_gm, o_gs, o_ym = out["flags"], out["n_grav_made"], out["n_grav_skipped"], out["n_yaw_made"]
    o_st = out["imu_status"]

    # The CS covariance only changes at a GPS event: cache its diagonal between them.
    cs_pdiag: list[float] | None = None
    for kind, i in zip(kinds.tolist(), idxs.tolist(), strict=True):
        if kind == _KIND_IMU:
            try:
                nav.imu(imu_t[i], imu_w[i], imu_f[i])
            except McaError as exc:
                o_st[i] = status_code(exc)
            if cs_pdiag is None:
                cs_pdiag = [float(ax.P[k, k]) for ax in nav.cs.axes for k in range(3)]
            o_t[i] = -1 if nav.t_imu_us is None else nav.t_imu_us
            o_q[i] = nav.q
            o_eul[i] = att.euler_from_quat(nav.q)
            o_b[i] = nav.b
            o_p[i], o_v[i], o_a[i] = nav._cs_extrapolated()
            o_Pc[i] = cs_pdiag
            o_Pa[i] = nav.P.diagonal()
            o_rpT[i] = nav.rp_T
            o_gT[i] = nav.gps_T
            o_fl[i] = nav.flags()
            o_gm[i] = nav.n_grav_made
            o_gs[i] = nav.n_grav_skipped
            o_ym[i] = nav.n_yaw_made
        elif kind == _KIND_GPS:
            try:
                nav.gps(gnss[i])
            except McaError as exc:
                out["gps_status"][i] = status_code(exc)
            cs_pdiag = None
        else:
            try:
                nav.mag(mag_t[i], mag_m[i])
            except McaError as exc:
                out["mag_status"][i] = status_code(exc)
    return out
