"""Backlash-aware position MPC: mode-switched condensed QPs on a gap model, solved by CasADi's conic.

Per sample the controller

1. updates two steady-state Kalman filters (motor and load encoders): one for the centre of inertia
   of the train (angle, speed, load-torque disturbance: integral action), one for the gap ``s`` and
   its rate ``v`` (report eqs 4-5, 11-12);
2. picks a *mode sequence* for the horizon (contact on the present flank; or separation from sample
   ``a`` and a landing on the other flank at sample ``e``) and solves, for that fixed sequence, ONE small
   dense QP in the torque sequence: load-angle tracking, torque about the rigid-train feedforward,
   torque rate, and at the planned landing the relative velocity (soft landing); constraints are the
   torque limit, the sign of the mesh torque in contact (a flank can push, never pull), the gap
   within the flanks while floating, the landing position (equality) and, with
   ``soft_landing = "bound"``, ``0 <= closing speed <= landing_velocity``;
3. in contact, it first solves the QP that stays on the flank; if its mesh-torque constraint binds
   (the plan would pull), it also solves the QP of a crossing centred there and applies the cheaper
   plan (full cost, constant part included). Floating, it solves the landing on the target flank after
   a countdown that only decreases (so the plan cannot keep postponing the landing) and, after an
   unplanned float (a bounce, start-up), the landing on the other flank too;
4. checks every solution (solver status; for CasADi plugins the KKT residual and feasibility too) and
   the step's solve time; on a
   failure or an overrun of ``max_solve_time`` it applies the previous plan's next input, saturated,
   and records the event in :attr:`~gearctl.design.base.Controller.fallbacks`; a reading the observer
   rejected or missed is recorded there too (see *Readings*).

The gap model
-------------
Coordinates ``z = [phi, omega, s, v]``: ``phi = (J1 theta1 + (J2/N) theta2) / J_eq`` is the motor-side
angle of the centre of inertia and ``omega`` its rate (the train's angular momentum over ``J_eq``,
which an impact does not change); ``s = r_b1 theta1 - r_b2 theta2`` and ``v = s'`` (eqs 4-5, 11-12).
Then ``theta1 = phi + kappa1 s`` and ``theta2 = phi / N - kappa2 s`` with
``kappa1 = J2 / (N r_b2 J_eq)``, ``kappa2 = J1 / (r_b2 J_eq)``.

- Separation (eqs 6-7): two free inertias with their viscous friction, discretised exactly (ZOH).
- Contact (eqs 1-3, 8-10) in the quasi-static limit of the mesh: the rigid train
  ``J_eq phi'' = xi1 + xi2 / N - d_eq phi'`` with ``s`` held and ``v = 0``; the mesh torque on the load
  is ``J2 theta2'' + d2 omega2 - xi2`` (eq 2), affine in the torques.
- Landing: a plastic impact in the reduced model (``v -> 0``, ``s -> sigma b``; momentum and the load
  angle kept).

Once the mode sequence is fixed the prediction is affine in the torques, so each pattern ``(a, e)`` has
constant QP matrices: all of them (about 140 for a horizon of 20) are condensed once in the
constructor, and a step only forms ``M p`` (gradient and constraint bounds at once) from the parameter
vector ``p`` (estimate, disturbance, reference preview, feedforward, last torque).

The backlash-free limit
-----------------------
A backlash estimate ``b = 0`` (e.g. the benchmark's backlash-free plant) is the limit of the design:
there is no gap, so no separation, crossing or landing pattern, and the mesh is a rigid coupling that
transmits torque both ways (with ``b = 0`` the plant's contact law ``F = k s + c s'`` acts on both
sides of ``s = 0``), so the sign constraint on the mesh torque is dropped. Each step solves the
contact QP alone (tracking, torque, torque rate, the torque limit, terminal weight: the rigid train),
one solve per sample. The gap is taken as ``s = v = 0`` (the mesh deflection ``F / k`` is far below
the encoders' resolution) and the gap filter is not designed; the centre-of-inertia filter, with its
load-disturbance estimate, still gives the integral action. The landing settings are then unused.
Solve-time recording, fallbacks, overrun handling and the solver path are those of ``b > 0``.

The same rigid design is taken for a gap the plan cannot resolve (:attr:`MPC.rigid_reason`, ``describe()``'s
``gap_model``): one the motor crosses within two samples at the crossing's quarter of the torque limit, or, with
the load encoder, one whose contact tolerance (at least three times the measured gap's noise std, from
``measurement_noise``; on a train at least the upstream stages' share of the lost motion, see
:func:`contact_tolerance`) would exceed half of it. Why: on ``shing1993_servo`` the gap design with b = 1e-7 to 1e-5
m landed every sample and flipped its flank every sample (sine RMS 2.7e-5, 0.012, 0.30, 0.88, 7.3e-5 rad for b =
1e-7, 1e-6, 3e-6, 5e-6, 1e-5; ``precision`` with 3e-6: A = 2.3 rad); the rigid design gives 9.2e-7, 3.5e-6,
1.0e-5, 1.7e-5, 3.3e-5 (A = 3.9e-5 rad), an error that falls smoothly with b to that of b = 0 (8.4e-7). From
2e-5 m (2.6 samples) the gap design is the better one (8.3e-6 against 6.5e-5 rad). A watch pair (1e-5 N m, 5 um)
is rigid by the same rule (0.85 samples). Where the gap design is kept, a ``smoothing`` above half the mesh torque
the torque limit gives the load (``J2 N u_max / (N^2 J1 + J2)``) is an :class:`~gearctl.errors.InputError`: every
landing plan would be infeasible (before: "gearctl QP: infeasible" on every step, the load never moved).

Notes
-----
*Mode-switched model rather than a smooth contact law.* The mesh mode (2.8 kHz on the benchmark servo,
lightly damped) lies above the 1 kHz sample rate: a smooth or stiff contact law in the prediction
would have to be integrated well below the sample period and solved as an NLP (IPOPT or fatrop:
milliseconds per solve), while torque held over 1 ms cannot shape the mesh mode anyway. With the mesh
quasi-static the plant is piecewise affine in ``z``; only the timing of a flank change is
combinatorial, and comparing the costs of "stay" and "cross at the binding sample" decides it with one
or two convex QPs per sample instead of a mixed-integer program. The price: the plan cannot shape the
bounces after an impact, only the speed at which the flanks meet, and it lands onto a flank that
carries at least ``smoothing`` of mesh torque, so the impact cascade dies out instead of being landed
again and again.

*Observer.* Impacts conserve momentum, so the centre-of-inertia filter is the rigid train in every
mode and never needs the mode. The gap filter predicts with the separation model and trusts it
(small gain) unless the innovation shows an impact (large gain); when the encoders show contact it
applies the reduced model's plastic impact (``v = 0``). With the motor encoder alone the gap is
predicted open loop and pinned at the flank it reaches.

*Solver path.* The QP has ``horizon`` variables and ``horizon + 2`` constraint rows, dense. The default
solver, ``solver = "gearctl"``, is gearctl's own dense dual active-set solver (:class:`gearctl.qp.DenseQP`,
``csrc/qp/gearctl_qp.c``), the code the exported C controller runs, so that Python and C give the same
torques: each pattern's Hessian is factored once (one :class:`~gearctl.qp.QPFactor` per pattern, its rows
kept in C order), and a solve copies the gradient and the row bounds into the solver's buffers and starts
cold (from the unconstrained minimiser; no primal warm start, so a solution does not depend on the
history of solves). It is exact: its status (solved, infeasible, iteration limit, numerical) replaces the
KKT check, and inactive multipliers are exact zeros, which the crossing decision reads. On the benchmark
servo it solves in 4 us median (50 us p99) per step, and tracks the 1 Hz sine to 2.9e-6 rad RMS against
2.7e-5 rad with DAQP through CasADi, which stops at constraint violations of up to its ``primal_tol``
(1e-6) on some landing QPs (``tests/test_qp.py``). Without a C compiler (or with ``GEARCTL_NO_COMPILE=1``)
``gearctl`` falls back to CasADi's ``qrqp`` plugin called through ``casadi.conic`` (an exact active-set
solver too: the same torques, measured to 1e-10 N m, but 70 us median and up to 0.2 s per solve here);
:meth:`MPC.describe` then says so (``qp_solver``, ``solver_note``).

The CasADi plugins stay available (``daqp``, ``qrqp``, ``osqp``, ``proxqp``). Called from Python, a CasADi
Function costs 25-40 us of call overhead on the 2-core benchmark machine before the solver runs (daqp
through ``casadi.conic``: 65-130 us median, up to 250 us at the 99th percentile). So for ``daqp`` and
``qrqp`` the conic, with the KKT check appended, is generated as C by CasADi's code generator, compiled
once with the system C compiler into the per-user cache (as :mod:`gearctl.kernel` does) and called
through :mod:`ctypes` on preallocated buffers: 5-30 us per solve with daqp. Without a C compiler the conic
is called through CasADi. ``osqp`` and ``proxqp`` always go through CasADi (0.5-1 ms per step here), and
qrqp's generated code needs about 2 ms on this QP. Python's cyclic garbage collector is paused during the
solver call (and restored at once), so that a collection (4-8 ms here) lands in the step overhead, which
:attr:`MPC.step_times` measures, not inside the solve. The backends (gearctl's solver, the CasADi plugins, compiled or
called through CasADi, and the muting of the plugins that print) are in :mod:`gearctl.design.mpc_solvers`.

*Checking a CasADi solve.* CasADi's generated daqp code reports success on an infeasible QP (the setup
failure is ignored), so every CasADi solution is checked: primal feasibility and the stationarity residual
``H x + g + lam_x + A' lam_a`` relative to the data, against a tolerance per solver (rows are scaled to
O(1): the gap in ``b``, its rate in ``b / Ts``, mesh torques in N m).

*Warm starts.* For the CasADi plugins the shifted previous plan and bound multipliers are passed as
``x0`` and ``lam_x0``; qrqp, osqp and proxqp use them, DAQP's CasADi interface starts from the
unconstrained minimiser. The shifted plan is also the fallback (for every solver).

*Scaled to the plant.* The torque weights and the observer's process noise are stated in shares of the
torque limit, so the catalog's settings give a 1 N m servo and the 7.7 mN m Quanser SRV02 the same
closed-loop bandwidth relative to what their motors can do (stated in N m, the SRV02's torque costs were
17000 times too cheap and its disturbance estimate as noisy as its whole torque). For a 1 N m limit nothing
changes. Measured on ``servo_3stage_quanser_srv02``, 1 Hz sine, RMS: 3.1e-3 rad before either change, 5.9e-4
with the train's contact tolerance alone, 4.6e-3 with the scaling alone, 1.4e-4 with both.

*Trains.* The MPC plans on the equivalent pair (:meth:`gearctl.plant.Plant.equivalent_pair`: one gap of the
whole lost motion at the output, the stages' series stiffness), measured by the motor and load encoders,
rather than on every stage. It sees only the two outer shafts: the intermediate ones are not measured, and
each floating stage would multiply the mode sequences of the plan by three. The price is that the measured
gap falls short of ``+-b`` while the intermediate shafts float between their flanks although the last stage
already carries the load: contact is then declared within :func:`contact_tolerance` of the flank (0.02 b
for a pair; plus the share of the lost motion of every stage but the last for a train), otherwise the plan
never leaves its landing patterns (the figures above). The intermediate shafts are still hit at the
crossing's speed and bounce between their flanks at every reversal: that remains the limit of the
equivalent model (4.8x better than the PID on the three-stage train, 226x on the pair; see
``tests/test_trains.py``). Where the intermediate shafts carry over :data:`INTERMEDIATE_SHARE` (15 %) of the motor
side's inertia (:func:`intermediate_share`) the plan is far off: 1.2x on ``servo_2stage_phm09`` (33 %), 0.2x on a
two-stage gravity joint (19 %), a rattle at rest; :func:`build_mpc` adds a design note pointing to the inverse.

*A backlash estimate that is too large.* The gap never reaches ``b - tol`` then, and the plan would keep
landing. Where the measured gap turns back on one side (its furthest point on that side, come back to
within ``tol`` on two later samples) short of ``b - tol`` (on a train, short by twice the tolerance less a
pair's: the floating intermediate shafts alone leave it short by up to the tolerance), that side's flank is
taken there: it decides contact and where landings aim from then on. The furthest point only grows, so a
flank taken short of the true one moves out when the gap goes further.

*Friction.* The model's Coulomb friction on the motor (``coulomb_friction1``; on a train, the equivalent pair's)
enters the plan as a torque on the motor, constant over the horizon, at the estimated motor speed: full above
``w_f`` and ramped through zero below it, where ``w_f`` is the smooth law's ``coulomb_velocity`` and at least ten
``measurement_noise`` per sample (the speed the estimate's noise gives). The QP then plans the torque that acts
on the motor, the drive's plus the friction; its bounds move with the friction and the drive's torque is the
plan's less the friction. The observer predicts with it too. It is left out while the plan holds (at rest the
friction is whatever the drive's torque asks of it). Why: with 1 % of the torque limit of motor friction
(``tests/data/motor_friction.toml``) every landing was planned for the next sample and none happened, the friction
holding the motor back: move RMS 23 mrad, now 0.23 mrad. Its ISO 230-2 reversal value on that plant rose from 73
to 430-480 urad (not yet understood).

The model's Coulomb friction on the load (``coulomb_friction2``) acts against the direction the reference moves,
as in the dead-zone inverse and the PID's friction feedforward: ``-T_c2 sgn``, with ``sgn`` the sign of ``r'``
or, where the reference rests, of its last motion (the friction that held the load when it stopped). The plan's
load torque is the disturbance estimate plus its mean over the previewed ``r'_{1..N}`` (a reversal within the
horizon gives the share of each direction); the observer predicts with that of ``r'_0``, so that its
disturbance estimates what the model does not give. Before, the disturbance estimate carried the friction and
took some 50 ms to follow its change of sign at a reversal, while the stuck load fell behind. Measured, ``gearctl
track MODEL mpc``, sine RMS before / after: POM pair (``tests/data/plastic_pom.toml``) 3.9e-3 / 6.8e-4 rad (its
PID 1.9e-3), ``shing1993_servo_friction`` 2.3e-4 / 1.1e-4, a three-stage train with load friction 1.3e-4 /
2.3e-5; the move on ``shing1993_servo_friction`` 4.5e-5 / 9.3e-6 rad, its ISO accuracy 9.1 / 8.7 urad. Not
everything gained: the move on ``tests/data/motor_friction.toml`` went from 1.3e-4 to 2.3e-4 rad, and the
three-stage train's ISO accuracy from 173 to 238 urad.

*Stalled landings.* A friction the model does not give, or encoders too coarse for the contact tolerance, can
still leave a planned landing short of its flank: the gap stops a few percent of ``b`` short, the observer's gap
speed biased by the unmodelled torque, and every sample plans the landing for the next one. With the load
encoder, a landing that has been due for ``n_cross + 5`` samples (:data:`_STALL_SAMPLES`) while the gap stays
within a quarter of ``b`` of the flank (:data:`_STALL_SHARE`) has stalled: contact is taken where the gap stopped,
on that side, until the gap goes further. Measured: ``gearctl track shing1993_servo_friction mpc --set
coulomb_friction1=0.02`` 0.11 rad RMS before (the load left behind while the reference moved on), 2.0e-3 rad with
it (4.1e-5 with the load's friction in the plan as well, 5.4e-4 once a torque at the QP's bound was the limit
exactly: a chaotic loop); a POM pair with 4096-count motor encoders, ISO accuracy
1.16 rad before, 23 mrad with it (0.70 mrad with the encoders' noise and the load's friction, below). An unknown
motor friction of 5 % of the torque limit still defeats the plan on the sine (0.11 rad RMS; the move 1.4e-3 rad):
estimating it is future work.

*Standstill.* While the previewed reference rests (constant over the whole horizon), the load is slow (its
estimated speed would not carry it one ``standstill_deadband`` further within the horizon) and within the
deadband of the reference, the plan *holds*; once holding, it holds while the load stays within three
deadbands (:data:`_STANDSTILL_RELEASE`), so that a free load coasting a little past the deadband is not
chased. Holding:

- no flank change is planned: no crossing in contact, no flip when floating; a load that floats off its
  flank is met on the flank the gap closes on by itself, when it does, at 5 % of ``landing_velocity`` and
  without the ``smoothing`` push; if it comes to rest on the other flank, that flank holds it;
- the flank in contact pushes the load towards the reference only if it can: when the load is past the
  reference on the side this flank cannot bring it back from (it cannot pull), and no load torque presses
  the load onto the flank (which could bring it back), the plan holds the load where it is instead of
  asking for the reference;
- with no load torque to hold against (the estimate below 1 % of the torque the motor can put on the load,
  :data:`_HANDS_OFF_TORQUE`) and once the plan has let go (its last torque below 0.1 % of the limit), no
  QP is solved and the torque is zero.

A larger error, or a fast load, is corrected as in motion.

Why (measured on ``gearctl track shing1993_servo mpc --reference move --duration 20``, 0.2 rad move, then
rest): before these rules the plan hunted across the gap for as long as the reference rested, about 370
flank changes and 500 impacts in the last 10 s (``shing1993_servo_friction``: 157 and 178; the pinion
model: 388 and 540), a sustained limit cycle. Two mechanisms fed it. (1) At rest a gap drifting towards the
other flank was met on that flank within the horizon: a full 2 b crossing in 20 ms that landed at 5e-4 to
1e-3 m/s (the contact declared 2 % of b early, the contact plan pushing at once) and rebounded, which read
as a drift towards the first flank again. What started the drift: on a friction-held load, the integral
action unwinding the motor's push (the load did not move, so the disturbance estimate took the push over
and the plan lowered its torque until the motor backed off the flank); on a free load, the rebound of the
previous landing. (2) In contact, the plan compensated the disturbance estimate and braked the estimated
speed, both of which jump by one encoder count's worth (1.5e-5 rad in the centre of inertia, 2.4e-4 rad/s
at the load) whenever a count changes: each jump gave the free load a kick of a few 1e-4 rad/s, which its
viscous friction (2.3 s time constant) let carry it out of the deadband, where the motion-grade correction
kicked it harder. Now: 0 flank changes after the move on the three models over 5 to 30 s; a free load
coasts to rest where the move's last few 1e-4 rad/s take it (measured 3.4e-4 to 4.9e-4 rad on
``shing1993_servo``, within the three-deadband hold), a friction-held load is pushed to within a few urad.
Holding a free load exactly needs a preloaded (anti-backlash) train.

*Readings.* A finite encoder reading whose innovation (its distance from the shaft angle the prediction puts it at)
differs from the last accepted reading's by more than :attr:`MPC.reading_gate` (along the line of action, what the
torque limit moves the motor in one sample, from full torque one way to full the other, plus twice the lost motion;
on each shaft, plus two counts and twelve noise stds of that encoder; 0.015 rad at the motor and 3.8e-3 rad at the
load on ``shing1993_servo``) is rejected. The predicted angles take the gap within the flanks (and none for the
rigid plan). A wild reading moves the
innovation at once; a prediction that drifts off, as under a load step that a slow estimate (noisy encoders) has
not yet followed, moves it a little every sample and is corrected. Gating the innovation itself took such a drift
for broken encoders: 2e-4 rad of encoder noise and a 0.5 N m load step latched the fault and the load ran off (0.34
rad RMS; now 2.8e-3). A rejected reading is not used: the estimate is the prediction alone on that sample, the plan
runs on it and the step is reported in :attr:`~gearctl.design.base.Controller.fallbacks` (the exported C returns a
fallback). A reading rejected on more than 4 samples in a row (:data:`_GATE_PERSIST`) is taken as the truth: the
estimate restarts from it as on the first sample. A load reading not finite or beyond :data:`INPUT_LIMIT` is a
missing one (the motor encoder alone, as with ``feedback = "motor"``), also reported; such a motor reading is a
missed sample, as in the exported API (zero torque, the estimate and plan unchanged, reported); the next step that
runs first carries the estimate over the missed samples, with the prediction alone (the zero torque acting), as for
a rejected reading (:data:`_MISSED_PREDICT`). So is a load reading
that puts the encoders' gap ``rb1 y_motor - rb2 y_load`` beyond :attr:`MPC.gap_limit` (2.5 b, four times the mesh's
static deflection under the torque limit and the load torque, the contact tolerance, and a count and six noise
stds of each encoder: 1.3e-4 m on ``shing1993_servo``, 2.6 b; none with a backlash estimate of 0): no gap the gear
allows explains it, so the load encoder is wrong, or zeroed off the motor's. (Without the encoders' term a train
with a 1024-count load encoder, 6.1e-3 rad a count, had 99 % of its load readings refused, and the sine ran at 0.08
rad RMS on the motor encoder alone.) Before, a load encoder that read 0.1 rad for 50 samples restarted the
estimate from it, the plan drove the motor to close the "gap" and the fault latched with the load 0.69 rad away;
one zeroed 10 mrad off the motor's sent the load 0.2-0.9 rad away with no fallback reported. Before, one reading
of 1e300 rad drove the estimate off and the load 116 rad away within a second (the exported C: 455 rad in 2 s).

*Coarse load encoders.* On a pair whose load encoder reads with a larger error (quantisation and noise) than the
motor's, and on any plant where a count of the load encoder is over the lost motion at the load (the encoder cannot
resolve the gap), :func:`build_mpc` has the observer weigh the load reading by its own error rather than the motor
encoder's, in the centre of inertia and the measured gap (and the contact tolerance). On a pair the observer's gap
model is exact, and a Kalman filter weighs each reading by its error; on a train the motor reads the load through
gaps the one-gap model leaves out, so there a load reading is never weighed below the motor's unless a count is over
the lost motion. Why: a 65536-count load encoder beside a 2^18-count motor encoder
(``tests/data/reviewer_pair_24x72.toml``), weighed as the motor's, made the plan's flank come and go at each
reversal (the torque chattered on half the samples): sine 1.7e-3 rad RMS, step 1.1e-2, ISO A 5.6 mrad, each worse
than the PID; weighed by its own error 1.0e-3, 1.2e-3 and 2.2 mrad. The catalog servo with a 2^18-, 2^16- or
2^14-count load encoder: sine 2.8e-4 / 7.2e-4 / 1.1e-3 rad RMS, now 1.5e-4 / 4.3e-4 / 4.3e-4 (its ISO accuracy with
the two coarser ones 0.93 and 0.76 mrad, now 1.5 and 1.8); ``tests/data/gravity_arm_17x119.toml`` with a
65536-count load encoder ran away (sine 0.18 rad RMS), now 1.2e-5. On the three-stage catalog train with a
65536-count load encoder the same weighting took the sine from 3.1e-4 to 6.1e-4 and the step from 1.1e-3 to 8.3e-3:
trains keep the motor's weight. If the
plan is then the rigid train's, the centre of inertia is measured by the motor encoder alone (as with ``feedback =
"motor"``): the motor's angle, through a gap far below a load count, places the load better than the load encoder
does. Why: on two fuzzed trains with a 10 000-count load encoder (a count 29 times the 22 urad lost motion) the
load reading, weighed as the motor's, put the ISO accuracy at 624 and 1078 urad against the PID's 15 and 17 (now
14 and 15, the motor encoder's error counted with the gap it reads through; the sine 4.6e-5 to 1.5e-5 rad RMS, the
PID's 1.3e-4); on ``tests/data/coarse_encoders_train.toml`` (1024 counts) ISO accuracy 3.6 mrad, now 0.23 (the PID's
0.87), and the sine 5.5e-4 to 4.6e-4 rad. More generally,
under a rigid plan (which does not track the gap) with encoders of different errors, the centre of inertia is
measured as ``y1 - c s_m`` with the ``c`` of least error variance, the gap taken uniform within ``+-b``:
``c = (kappa1 b^2/3 + rb1 s1^2) / (b^2/3 + rb1^2 s1^2 + rb2^2 s2^2)`` (``kappa1``: the exact centre, gap-free;
0: the motor encoder alone; ``1 / rb1``: the load encoder alone). On a review's small pair with a noisy 4096-count
motor encoder and a 65536-count load encoder (``tests/data/noisy_motor_encoder_pair.toml``) the ISO accuracy went
from 1579 to 246 urad (the PID's 167) and the sine from 3.3e-5 to 2.0e-5 rad RMS (the PID's 5.8e-5).

*A fault.* Three restarts of the estimate within 1000 samples (:data:`_FAULT_RESTARTS`, :data:`_FAULT_WINDOW`)
mean that the readings follow no motion the model allows (a broken encoder, a loose connector): :attr:`MPC.fault`
latches until :meth:`MPC.reset`, every step is reported in ``fallbacks``, and the motor is braked to rest from its own
reading's changes (the speed from two changes in the same direction, decaying as the braking takes it, time constant
:data:`_BRAKE_TIME`), then the torque is zero. Why: readings the plan restarted from at rest again and again (16- and
4-count encoders, before the gate allowed for a count) drove the load 2.9 rad away (the review: 43 rad); zero torque
at the fault let it coast 14.6 rad; braked, it stopped within 0.39 rad. Such encoders are now read as counts (largest
error 0.24 rad on the sine, the PID's 0.15); a motor reading 0.5 rad off for 6 samples twice latches the fault
(``tests/test_mpc_cases.py``). A load torque still moves a faulted drive (the brake is a damper, not a position
hold).

*Crossings.* A crossing still on its old flank (the gap has not left it) is re-decided every sample: the plan that
stays in contact there is solved too and taken if it is cheaper by :data:`_CROSS_MARGIN`. Why: on
``servo_3stage_quanser_srv02``'s step the 0.5 N m load step (the drive holds 0.54 N m at the load) arrived just
after the plan had committed to the back flank; the load torque held the gap shut on the front flank, the plan
only counted down a landing that could not happen, and the load ran off to 31 rad. Now 7.9e-3 rad at most, back
to 4.7e-7 rad.

*Angles.* The QP's parameters hold angles from an origin, the reference at ``t``: the estimate's motor-side
angle ``phi - N r(t)`` and the previewed ``r_k - r(t)``. Fed absolute angles, the QP's gradient summed terms
of the size of the angle times the tracking weight that cancelled: at 1e4 rad (a double's spacing there is
1.8e-12 rad) the torques came out wrong by up to the torque limit. Now a controller fed the same readings
and reference shifted by 1e4 rad gives the same torques to 1.5e-8 N m (the rounding of the offset). The gap
model's dependence on ``phi`` is set to exactly none (the similarity transform left 1e-18 there).

*Preview.* The MPC reads ``horizon + 1`` reference samples per step (``r(t)`` to ``r(t + N Ts)``, with the
feedforward over the horizon): :attr:`MPC.preview` and ``describe()["preview"]`` say so, and the bench
table shows it beside the PIDs' 1. It therefore starts moving up to ``horizon`` samples before a step of
the reference, which a controller that reads ``r(t)`` only cannot (a step the plan cannot stop within its horizon is
given to it as a profile that starts at the step: *Large steps*).

*Large steps: a reference governor.* The plan sees ``horizon x Ts`` ahead (20 ms in the catalog). After a jump of
the reference that saturates the torque, the stop takes longer than that, so the plan brakes late: on
``shing1993_servo`` a 2 rad step peaked at 2.97 rad (48 % over) and a 20 rad one at 35.5 rad; on a reviewer's pair
(``tests/data/reviewer_pair_24x72.toml``) with a horizon of 13 samples at 0.5 ms a 20 rad step peaked at 208 rad.
The plan is therefore given a governed reference (:meth:`MPC._governed`; the exported C, ``gcx_mpc_govern``, does
the same arithmetic). Let ``a_net`` be the load's acceleration the torque limit leaves after the model's Coulomb
friction and load torque (``(u_max - T_c1 - (|tau_L| + T_c2) / N) / (N J_eq)``) and ``t_s = (horizon - n_cross) Ts``
what the horizon leaves after a crossing of the gap. A sample ``k -> k + 1`` of the reference is given to the plan
as it is where its angle jumps (beyond what its speeds explain, by the trapezoid rule) by at most ``a_net t_s^2`` (a
jump the plan stops alone within its horizon at the torque limit) and its acceleration is at most ``a_net``. A
reference made of such samples (the sine, the moves, the ramp, the catalog's 0.05 rad step on ``shing1993_servo``)
reaches the plan bit for bit as before; so does one that starts in motion (the sine) from a load within ``a_net
t_s^2`` of it. A jump of the reference's speed alone (a ramp's start and end) is left to the plan: a profile off the
reference would brake it at a quarter of ``a_net``, where the plan brakes it at the limit and starts ``horizon``
samples early (a 20 rad/s ramp's end: 2.6 rad past it governed, 0.37 rad as before; see below). Any other sample
takes the governor off the reference: the governed
angle then moves with the reference's own speed change (up to ``a_net`` in all) and closes on it with the discrete
time-optimal profile, in the frame that moves with it (:func:`_governor_step`), at :data:`_GOVERNOR_SHARE` (a
quarter) of ``a_net``, at most as fast as the speed at which the viscous friction leaves the profile that share, and
at most ``a_net t_s^2`` and ``a_net t_s`` ahead of the load's estimated angle and speed (a load that lags the profile
holds it back, so the plan is never asked to catch up more than it stops within its horizon). It is back on the
reference at the sample where it comes within ``a_net Ts^2`` and ``a_net Ts`` of it (what the plan takes in a
sample). The governor is run over the whole preview each step (``horizon`` samples, a bounded loop), so the plan sees
the profile's stop as it saw the reference's.

Why a reference governor: it leaves the QP, its tables and a feasible reference as they were, and makes every stop
the plan is asked for one it sees within its horizon. Why a quarter of ``a_net`` (the share a planned crossing
uses): with half, the plan could not follow the profile on two review models (each reversal of the torque is a
crossing it lands softly), fell behind and caught up late: 2 rad steps 22 % over on the reviewer's pair and 14 % on
``tests/data/tight_torque_servo.toml``; with a quarter, 0.2 % and 0.1 %. Why the reference's own jumps up to what
the plan stops alone pass: governed, the catalog's 0.05 rad step ends on the braking flank, and its 0.5 N m load
step then needs a crossing (largest error 1.5 mrad before, 2.9 governed). Measured, overshoot of a step through
:func:`~gearctl.closedloop.simulate_closed_loop`, before / after (the PID): ``shing1993_servo`` 0.2 rad 2.4 / 0.0 %
(7.3), 2 rad 48 / 0.0 % (40), 20 rad 77 / 0.0 % (71); the reviewer's pair 18 / 8.7 % (6.3), 33 / 0.2 % (39),
55 / 0.0 % (62), with horizon 13 at 0.5 ms 76 / 0.4, 96 / 0.1, 939 / 0.0 %; ``tight_torque_servo`` 21 / 0.6 % (8.9),
55 / 0.0 % (35), 54 / 0.0 % (76); ``servo_3stage_quanser_srv02`` 9.2 / 0.5 % (4.3), 20 / 0.0 % (15), 6.1 / 0.0 %
(5.6). A 2 rad step added to the 1 Hz sine at 0.3 s went 0.97 rad past the reference on ``shing1993_servo``, now
0.3 mrad; on ``tests/data/coarse_encoders_train.toml`` (a weak drive: a quarter of its 6.7 rad/s^2 is below the
sine's 3.9) 0.10 rad, now 0.24 mrad. The price: a governed step is slower to start than the plan's own (0.2 rad on
``shing1993_servo`` within 2 % after 93 ms, 61 ms before), while the large ones settle sooner (2 rad: 295 against
381 ms; 20 rad: 0.94 against 3.0 s). The plan's own small steps are not changed: on the reviewer's pair a 0.01 rad
step still overshoots 17 % and a 0.05 rad one 30 % (landings, not the horizon). Nor is a reference whose speed is
beyond what the plan stops within its horizon (``a_net t_s``, 4.4 rad/s on ``shing1993_servo``) and which then stops
at once: a 20 rad/s ramp still ends 0.37 rad past its end, as before (a move at 1e4 rad/s^2, beyond ``a_net``, is
governed: 10.4 rad past its end before, 2e-5 now).

*A solver plugin that is not installed* is an :class:`~gearctl.errors.InputError` when the controller is
built (not a silent switch to another solver, which would make the solve-time figures describe a
different controller). qpOASES is in the wheel but prints a banner from C when it is built, and hpipm
needs a structured (OCP) problem, so neither is offered.

References
----------
T. K. Shing, L. W. Tsai, P. S. Krishnaprasad, ISR TR 93-28 (1993), section 2, eqs 1-12 (the plant).
M. Nordin, P.-O. Gutman, "Controlling mechanical systems with backlash - a survey", Automatica 38
(2002) 1633-1649. P. Rostalski, T. Besselmann, M. Baric, F. Van Belzen, M. Morari, "A hybrid approach
to modelling, control and state estimation of mechanical systems with backlash", Int. J. Control 80
(2007) 1729-1740. D. Arnstrom, A. Bemporad, D. Axehill, "A dual active-set solver for embedded
quadratic programming using recursive LDL' updates", IEEE Trans. Automatic Control 67 (2022) 4362-4369.
D. Goldfarb, A. Idnani, "A numerically stable dual method for solving strictly convex quadratic
programs", Math. Programming 27 (1983) 1-33 (the ``gearctl`` solver).
"""

from __future__ import annotations

import dataclasses
import gc
import math
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import scipy.linalg
from numpy.typing import NDArray

from ..controller import ReferenceLike
from ..errors import InputError
from ..files import Binding, Layout, build_dataclass, spec_values
from ..limits import MAX_OUTPUT_BYTES, available_memory
from ..params import FrictionLaw, Sensors
from ..plant import Plant, input_matrix, mode_matrices
from ..units import BACKLASH, check_choice, quantity, validate_fields
from .base import Controller, LoopInfo, check_loop_info
from .mpc_solvers import SOLVERS, _make_qp, _plugin_loads, installed_solvers

__all__ = ["MPC", "MPCSettings", "build_mpc", "SOLVERS", "installed_solvers", "KIND", "LAYOUT"]

#: Readings beyond it (or not finite) are a missed sample, as the exported API's ``GEARCTL_INPUT_LIMIT`` [rad].
INPUT_LIMIT = 1e12

#: The controller-file kind this module builds (:mod:`gearctl.design.registry`).
KIND = "mpc"
#: The least ``measurement_noise`` [rad] (the default without sensors): about one count of a 2^20-count encoder
#: (6e-6 rad quantises to 1.7e-6 rad rms). A model's coarser or noisier encoders raise the default (build_mpc).
MEASUREMENT_NOISE_FLOOR = 2e-6
#: The default ``smoothing`` [N m] where the torque limit allows it (see :func:`build_mpc`).
SMOOTHING = 2e-3

SOFT_LANDING = ("penalty", "bound", "off")
FEEDBACK = ("load", "motor")


# --- settings --------------------------------------------------------------------------------------------


@dataclasses.dataclass(frozen=True, slots=True, kw_only=True)
class MPCSettings:
    """Settings of the backlash-aware MPC (the ``kind = "mpc"`` controller file).

    Attributes
    ----------
    horizon : int
        Prediction and control horizon [samples].
    solver : str
        QP solver, one of :data:`SOLVERS`: ``"gearctl"`` (default; :class:`gearctl.qp.DenseQP`, exact,
        the solver the exported C controller runs) or a CasADi conic plugin.
    feedback : str
        ``"load"``: motor and load encoders (the gap is measured); ``"motor"``: motor encoder only (the
        load and the gap are predicted open loop in separation).
    tracking : float
        Weight of the load-angle error at every predicted sample [1/rad^2].
    torque : float
        Weight of the torque's deviation from the rigid-train feedforward, the torque counted in shares of
        the torque limit [1] (so that one file suits a 1 N m servo and an 8 mN m one; with a 1 N m limit it is
        the weight per (N m)^2).
    torque_rate : float
        Weight of the torque change per sample, in shares of the torque limit [1].
    relative_velocity : float
        Weight of the closing speed's deviation from ``landing_velocity`` at a planned landing, along the
        line of action [s^2/m^2].
    terminal : float
        Extra weight at the last sample, as a multiple of ``tracking``, on the load-angle error and on
        the load-speed error times half the horizon time.
    soft_landing : str
        ``"bound"``: ``0 <= closing speed <= landing_velocity`` as a hard constraint, plus the penalty;
        ``"penalty"``: the ``relative_velocity`` penalty alone; ``"off"``: neither (hard landings).
    landing_velocity : float
        Closing speed of a planned landing [m/s]: the bound, and the penalty's target.
    max_solve_time : float
        A step whose QP solves take longer than this counts as an overrun [s]; it falls back only where
        ``realtime`` is set (``--realtime``), as on the target.
    smoothing : float
        Mesh torque on the load the plan must leave on a flank at the first sample after a landing
        [N m]: the impacts then die out quickly instead of the motor floating off and landing again.
    process_noise : float
        Observer: std of the unmodelled torque on each shaft per sample, and of the load-torque
        disturbance's change per sample, as a share of the torque limit [1].
    measurement_noise : float
        Observer: std of each encoder's error [rad]. A controller file that does not set it gets the model's
        motor encoder's (:func:`build_mpc`; a 4096-count encoder: 4.4e-4 rad), at least
        :data:`MEASUREMENT_NOISE_FLOOR`.
    standstill_deadband : float
        Load error [rad] within which the plan holds its flank while the previewed reference rests (see
        *Standstill* in the module docstring); ``0 <= value <= 1``.
    backlash : float or None
        Backlash estimate ``b`` [m], ``0 <= b < 0.01``. With ``b = 0`` the train is taken as backlash-free
        (see *The backlash-free limit* in the module docstring): the landing settings (``soft_landing``,
        ``landing_velocity``, ``relative_velocity``, ``smoothing``) are then unused. ``None`` (the default): the
        design plant's, as a controller file without the key gets (:class:`MPC` resolves it). Before, the default
        was the benchmark servo's 5e-5 m whatever the plant: ``MPC(info, MPCSettings(horizon=20))`` on
        ``servo_3stage_quanser_srv02`` (3.0e-5 m) planned on a gap 1.7 times the train's and ran the load off
        (1.3 rad RMS on the sine; the catalog file: 2.1e-4 rad).

    Raises
    ------
    InputError
        For a value of wrong type or out of range (named), a ``solver``, ``feedback`` or ``soft_landing`` not
        among its choices, or ``torque = 0`` with ``torque_rate = 0`` (field ``torque``).
    """

    horizon: int = quantity(unit="samples", doc="prediction and control horizon", low=1, high=200, integer=True,
                            default=20)
    solver: str = "gearctl"
    feedback: str = "load"
    tracking: float = quantity(unit="1/rad^2", doc="load-angle error weight", low=0.0, low_open=True, high=1e15,
                               default=1e8)
    torque: float = quantity(unit="1", doc="torque weight, torques in shares of the torque limit", low=0.0,
                             high=1e15, default=1e-2)
    torque_rate: float = quantity(unit="1", doc="torque-rate weight, torques in shares of the torque limit",
                                  low=0.0, high=1e15, default=300.0)
    relative_velocity: float = quantity(unit="s^2/m^2", doc="landing-speed weight", low=0.0, high=1e15, default=1e7)
    terminal: float = quantity(unit="1", doc="terminal weight over tracking", low=0.0, high=1e6, default=10.0)
    soft_landing: str = "bound"
    landing_velocity: float = quantity(unit="m/s", doc="closing speed of a planned landing", low=0.0,
                                       low_open=True, high=1.0, default=2e-4)
    max_solve_time: float = quantity(unit="s", doc="solve-time budget of a step", low=0.0, low_open=True, high=1.0,
                                     default=1e-3)
    smoothing: float = quantity(unit="N m", doc="mesh torque left on a flank after a landing", low=0.0, high=1e3,
                                default=SMOOTHING)
    process_noise: float = quantity(unit="1", doc="observer process noise, a share of the torque limit", low=0.0,
                                    low_open=True, high=1e3, default=1e-4)
    measurement_noise: float = quantity(unit="rad", doc="observer measurement noise", low=0.0, low_open=True,
                                        high=1.0, default=MEASUREMENT_NOISE_FLOOR)
    backlash: float | None = BACKLASH.field(default=None, optional=True,
                                            doc="backlash estimate (0: a backlash-free train; None: the plant's)")
    standstill_deadband: float = quantity(unit="rad", doc="load error below which the plan does not cross the gap "
                                          "while the previewed reference rests", low=0.0, high=1.0, default=2e-4)

    def __post_init__(self) -> None:
        if isinstance(self.soft_landing, bool):  # true/false in a file: the penalty alone / off
            object.__setattr__(self, "soft_landing", "penalty" if self.soft_landing else "off")
        validate_fields(self)
        object.__setattr__(self, "horizon", int(self.horizon))
        check_choice("solver", self.solver, SOLVERS, what="a QP solver")
        check_choice("feedback", self.feedback, FEEDBACK)
        check_choice("soft_landing", self.soft_landing, SOFT_LANDING)
        if self.torque == 0.0 and self.torque_rate == 0.0:
            raise InputError("torque = 0 and torque_rate = 0: at least one torque weight must be > 0 "
                             "(the QP needs a positive definite Hessian)", field="torque")


# --- reading a controller file ---------------------------------------------------------------------------



def build_mpc(path: Path, spec: dict[str, Any], info: LoopInfo, *, Ts: float, name: str,
              backlash: float | None = None, sensors: Sensors | None = None,
              progress: Callable[[float], Any] | None = None) -> MPC:
    """Build the MPC of a controller file (called by :func:`gearctl.design.registry.build_controller`).

    Parameters
    ----------
    path : Path
        The file, for messages.
    spec : dict
        The parsed TOML (keys already checked against ``CONTROLLER_KEYS["mpc"]``).
    info : LoopInfo
        Design-time plant knowledge.
    Ts : float
        Sample period [s].
    name : str
        Label.
    backlash : float, optional
        Backlash estimate overriding the file's ``backlash`` and the model's [m]; ``0 <= backlash < 0.01``,
        0 giving the backlash-free (rigid-train) MPC, e.g. on the benchmark's backlash-free plant.
    sensors : Sensors, optional
        The model's encoders. (Where the file does not set ``smoothing``, it is :data:`SMOOTHING`, or a quarter
        of the mesh torque the torque limit gives the load where that is less.) Where the file does not set
        ``measurement_noise``, it is the motor encoder's
        reading error (:meth:`Sensors.reading_std`: quantisation and noise), at least
        :data:`MEASUREMENT_NOISE_FLOOR` and at most 1 rad (the key's range); without sensors, the floor. The
        load encoder's own is not used: it reads the output itself, while the motor encoder reads it through the
        lost motion and compliance that the observer's rigid-train model leaves out, so the load reading is never
        weighed below the motor's. On an unseen three-stage train with a 65536-count load encoder (2.8e-5 rad
        rms) weighing it by its own error leaned on the 2^20-count motor encoder and took the sine from 1.3e-4
        to 7.6e-4 rad RMS. Except where a count of the load encoder is over the lost motion at the load (it
        cannot resolve the gap): the load reading is then weighed by its own error (``load_noise``; see *Coarse
        load encoders* in the module docstring).
    progress : callable, optional
        Called with the fraction of the design done (see :class:`MPC`).

    Returns
    -------
    MPC

    Raises
    ------
    InputError
        For a value out of range (naming ``file: key``) or an unknown or not installed solver. (A
        ``[design]`` table is rejected by the registry: the MPC is tuned by its ``[weights]``.)
    """
    values = spec_values(path, spec, MPC_LAYOUT, kind="mpc")
    # the file's keys, and the values the design supplies (no binding: no key of the file)
    vals: dict[str, tuple[Binding | None, Any]] = dict(values.get(MPCSettings, {}))
    vals.pop("_sample_time", None)  # the sample time is Ts (checked by the registry)
    if "solver" in vals:
        try:
            check_choice("solver", vals["solver"][1], SOLVERS, what="a QP solver")
        except InputError as exc:
            raise InputError(f"{path}: {exc}", field="solver", rule=exc.rule) from None
        if not _plugin_loads(vals["solver"][1]):
            raise InputError(f"{path}: solver = {vals['solver'][1]!r} is not installed in this CasADi: installed "
                             f"are {', '.join(repr(s) for s in installed_solvers())}", field="solver")
    if backlash is not None:  # the caller's estimate wins over the file's
        vals["backlash"] = (None, backlash)
    elif "backlash" not in vals:
        vals["backlash"] = (None, info.plant.backlash)
    if "max_solve_time" not in vals:
        vals["max_solve_time"] = (None, Ts)
    file_noise = "measurement_noise" in vals
    if "measurement_noise" not in vals and sensors is not None:  # the motor encoder's (see the docstring)
        # within the key's range: a reading error over 1 rad (a 4-count encoder, a noise of radians) is 1 rad
        vals["measurement_noise"] = (None, min(max(MEASUREMENT_NOISE_FLOOR, sensors.reading_std("motor")), 1.0))
    if "smoothing" not in vals:  # 2e-3 N m, or a quarter of the mesh torque the torque limit gives the load if less
        pl, N, umax = info.plant, info.N, min(info.torque_limit, 1e6)
        mesh_max = pl.J2 * N * umax / (N * N * pl.J1 + pl.J2)
        vals["smoothing"] = (None, min(SMOOTHING, _SMOOTHING_DEFAULT_SHARE * mesh_max))
        scaled_smoothing = vals["smoothing"][1] < SMOOTHING
    else:
        scaled_smoothing = False
    settings = build_dataclass(path, MPCSettings, vals)
    reading_error: tuple[float, float] | None = None
    if sensors is not None:  # a count and the noise of each encoder (the gap the readings may show: gap_limit)
        def error(cpr: int | None, noise: float) -> float:
            return 2.0 * math.pi / cpr + _NOISE_SIGMAS * noise if cpr else _NOISE_SIGMAS * noise

        reading_error = (error(sensors.motor_encoder_cpr, sensors.motor_noise),
                         error(sensors.load_encoder_cpr, sensors.load_noise))
    load_noise = load_std = None
    if sensors is not None and not file_noise:
        load_std = sensors.reading_std("load")
        # a count of the load encoder over the lost motion: weigh it by its own error (see *Coarse load encoders*)
        # a load encoder coarser than the motor's, on a pair (the gap model exact): weigh it by its own error; on a
        # train, or a count over the lost motion, see *Coarse load encoders*
        coarse = sensors.load_encoder_cpr and _COUNT_PER_STD * load_std > 2.0 * settings.backlash / info.plant.rb2
        if coarse or (info.nominal.n_stages == 1 and load_std > settings.measurement_noise):
            load_noise = load_std
    try:
        mpc = MPC(info, settings, Ts=Ts, name=name, reading_error=reading_error, load_noise=load_noise,
                  load_std=load_std, scaled_smoothing=scaled_smoothing, progress=progress)
    except InputError as exc:
        raise InputError(f"{path}: {exc}", field=exc.field) from None
    if mpc.rigid_reason and settings.backlash > 0.0:
        # the file asked for a backlash-aware plan and gets the rigid train's: say so where the notes go (track,
        # precision, bench print them), not only in describe()'s rigid_reason
        mpc.design_notes = (*mpc.design_notes, (
            f"gap model off: {mpc.rigid_reason}, so the MPC plans on the rigid train, as with backlash = 0 "
            f"(gap_model = 'rigid'): it does not plan the gap crossings; compare it with the deadzone_inverse "
            f"(gearctl bench MODEL)"))
    if settings.max_solve_time > Ts:
        # a budget over the sample period (a copy of the catalog file, 1e-3 s, at a shorter sample_time): the solve
        # times report a step as on time that a target running this period would miss; say so where notes go
        mpc.design_notes = (*mpc.design_notes, (
            f"max_solve_time = {settings.max_solve_time:g} s is over the sample period ({Ts:g} s): a step whose "
            f"solves take longer than the period would be late on a target, but counts as an overrun (and falls back "
            f"with --realtime) only beyond max_solve_time; set it to at most the sample_time"))
    share = intermediate_share(info.nominal)
    if share > INTERMEDIATE_SHARE and not mpc.rigid_reason:
        mpc.design_notes = (*mpc.design_notes, (
            f"train: the intermediate shafts carry {share:.0%} of the motor side's inertia (reflected), which the "
            f"one-gap plan does not see; on the four catalog and test trains above {INTERMEDIATE_SHARE:.0%} where it "
            f"plans the gap, the MPC gained at most 1.5x over the PID on the sine (1.07-1.25x, by machine, on "
            f"servo_2stage_phm09) and lost 5x on one, and it rattles at rest: the deadzone_inverse is the "
            f"controller for such a train"))
    elif (up := upstream_gap_share(info.nominal)) >= 0.01 and not mpc.rigid_reason:  # (under 1 %: no word)
        mpc.design_notes = (*mpc.design_notes, (
            f"upstream gaps: the plan sees one gap; the stages before the last hold {up:.0%} of the lost motion, "
            f"left to a contact tolerance, and their free shafts rattle at each crossing. On 13 trains with such gaps "
            f"the MPC's sine RMS ranged from 4.8x below the PID's to 8x above it (above on 5, among them every one "
            f"under a gravity load); compare it with the deadzone_inverse on this train (gearctl bench MODEL)"))
    return mpc


def upstream_gap_share(plant: Plant) -> float:
    """Share of a train's lost motion at the output in the stages before the last (0 for a pair): the gaps the
    one-gap plan leaves to its contact tolerance (see *Trains* in the module docstring)."""
    total = plant.lost_motion
    return sum(plant.stage_lost_motions[:-1]) / total if total > 0.0 and plant.n_stages > 1 else 0.0


#: Share of the motor side's inertia on the intermediate shafts above which :func:`build_mpc` notes that the
#: one-gap plan does not suit the train (see *Trains* in the module docstring).
INTERMEDIATE_SHARE = 0.15


def intermediate_share(plant: Plant) -> float:
    """Share of the motor side's inertia (the motor shaft and the intermediate shafts, reflected to the motor) that
    the intermediate shafts carry: 0 for a pair."""
    if plant.n_stages < 2:
        return 0.0
    motor_side = plant.equivalent_pair().J1  # the motor shaft and every intermediate shaft, reflected
    return (motor_side - plant.shafts[0].J) / motor_side


#: The keys of an ``mpc`` controller file and the settings fields they feed.
MPC_LAYOUT: Layout = {
    "": {k: (MPCSettings, k) for k in ("feedback", "horizon", "solver", "backlash", "soft_landing",
                                       "landing_velocity", "max_solve_time", "smoothing", "standstill_deadband")} | {
        "sample_time": (MPCSettings, "_sample_time")},
    "weights": {k: (MPCSettings, k) for k in ("tracking", "torque", "torque_rate", "relative_velocity",
                                              "terminal")},
    "observer": {k: (MPCSettings, k) for k in ("process_noise", "measurement_noise")},
}
LAYOUT = MPC_LAYOUT


# --- the gap model ---------------------------------------------------------------------------------------


def contact_tolerance(info: LoopInfo) -> float:
    """How far from a flank the equivalent gap may be and count as contact, as a share of ``b``.

    For a pair, 0.02 (the encoders resolve about 1 % of ``b``). For a train the controller measures only the
    motor and the load: its gap is the equivalent one, ``sum_i s_i / b_i * L_i / L``, and the intermediate
    shafts, unmeasured and free between their flanks, leave it short of ``+-b`` while the last stage already
    carries the load. The tolerance then adds the share of the lost motion ``L_i / L`` of every stage but the
    last: with those stages anywhere in their gaps the load is still driven within the horizon by a torque
    towards the flank.
    """
    nominal = info.nominal
    if nominal.n_stages <= 1 or nominal.lost_motion <= 0.0:
        return 0.02
    shares = nominal.stage_lost_motions
    return 0.02 + float(sum(shares[:-1])) / nominal.lost_motion


@dataclasses.dataclass(frozen=True, slots=True)
class _GapModel:
    """Discrete gap-model matrices at ``Ts`` (see the module docstring)."""

    A_sep: NDArray[np.float64]  # (4, 4) separation, z-coordinates
    B_sep: NDArray[np.float64]  # (4, 2) inputs [xi1, xi2]
    A_con: NDArray[np.float64]  # contact (quasi-static mesh): rigid train, s held, v = 0
    B_con: NDArray[np.float64]
    T: NDArray[np.float64]  # z = T x, x = [theta1, theta2, omega1, omega2]
    Ad_x: NDArray[np.float64]  # separation in x-coordinates (for the observer design)
    Bd_x: NDArray[np.float64]
    kappa1: float
    kappa2: float
    N: float


def _zoh(A: NDArray[np.float64], B: NDArray[np.float64], Ts: float) -> tuple[NDArray, NDArray]:
    n, m = B.shape
    M = np.zeros((n + m, n + m))
    M[:n, :n], M[:n, n:] = A, B
    E = scipy.linalg.expm(M * Ts)
    return E[:n, :n], E[:n, n:]


def _gap_model(info: LoopInfo, Ts: float) -> _GapModel:
    p = info.plant
    J1, J2, N, Jeq = p.J1, p.J2, info.N, info.J_eq
    A, B = mode_matrices(p, [False]), input_matrix(p)
    Ad, Bd = _zoh(A, B, Ts)  # eqs 6-7
    a1, a2 = J1 / Jeq, J2 / (N * Jeq)
    T = np.array([[a1, a2, 0, 0], [0, 0, a1, a2], [p.rb1, -p.rb2, 0, 0], [0, 0, p.rb1, -p.rb2]])
    A_sep, B_sep = T @ Ad @ np.linalg.inv(T), T @ Bd
    # translation invariance: phi enters as phi itself and nowhere else (the similarity transform leaves rounding
    # residues of 1e-18 there, which an absolute angle of 1e4 rad would turn into 1e-14 m of gap per sample)
    A_sep[:, 0] = (1.0, 0.0, 0.0, 0.0)
    Ac = np.array([[0.0, 1.0], [0.0, -info.d_eq / Jeq]])
    Bc = np.array([[0.0, 0.0], [1 / Jeq, 1 / (N * Jeq)]])
    Adc, Bdc = _zoh(Ac, Bc, Ts)  # rigid train: eqs 1-3 with k -> inf
    A_con = np.zeros((4, 4))
    A_con[:2, :2] = Adc
    A_con[2, 2] = 1.0  # s held, v = 0
    B_con = np.zeros((4, 2))
    B_con[:2] = Bdc
    return _GapModel(A_sep=A_sep, B_sep=B_sep, A_con=A_con, B_con=B_con, T=T, Ad_x=Ad, Bd_x=Bd,
                     kappa1=J2 / (N * p.rb2 * Jeq), kappa2=J1 / (p.rb2 * Jeq), N=N)


def _kalman_gain(A: NDArray, G: NDArray, Qw: NDArray, C: NDArray, R: NDArray) -> NDArray:
    """Steady-state gain of the filtered (measurement-updated) Kalman filter.

    SciPy's Riccati solver first; where it finds the symplectic pencil's eigenvalues too close to the unit circle
    (a plant whose scales span many decades: a fuzzed pair with a 10 um module and a 1e-15 kg m^2 load raised its
    ``LinAlgError`` as a traceback), the filter's own Riccati recursion, iterated to its fixed point.

    Raises
    ------
    InputError
        If neither gives a finite, converged solution (naming the observer's keys).
    """
    Q = G @ Qw @ G.T
    try:
        P = scipy.linalg.solve_discrete_are(A.T, C.T, Q, R)
    except (np.linalg.LinAlgError, ValueError):
        P = _riccati_iteration(A, Q, C, R)
    K = P @ C.T @ np.linalg.inv(C @ P @ C.T + R)
    if not np.all(np.isfinite(K)):
        raise InputError("process_noise / measurement_noise: the MPC's observer has no steady-state Kalman gain on "
                         "this plant (its Riccati equation gives no finite, converged solution); the plant's scales "
                         "span too many decades for it: use the pid or the deadzone_inverse", field="process_noise")
    return K


def _riccati_iteration(A: NDArray, Q: NDArray, C: NDArray, R: NDArray, steps: int = 100_000) -> NDArray:
    """The predicted covariance's fixed point of the Kalman filter's Riccati recursion (see :func:`_kalman_gain`);
    NaN where it diverges or does not converge within ``steps``."""
    P = Q.copy()
    for _ in range(steps):
        S = C @ P @ C.T + R
        Pn = A @ (P - P @ C.T @ np.linalg.solve(S, C @ P)) @ A.T + Q
        Pn = 0.5 * (Pn + Pn.T)
        if not np.all(np.isfinite(Pn)):
            break
        if np.allclose(Pn, P, rtol=1e-12, atol=0.0):
            return Pn
        P = Pn
    return np.full_like(P, np.nan)


# --- the controller --------------------------------------------------------------------------------------

_INF = 1e20  # "no bound" for constraint rows (finite: some plugins reject inf)
_CROSS_MARGIN = 2e-3  # a crossing must lower the plan's cost by this fraction (no flank change on a tie)
_FLIP_MARGIN = 0.1  # after an unplanned float, the other flank must be this much cheaper to land on
_FREE_ACCELERATION = 1000.0  # rad/s^2 at the motor: without a torque limit, torques are weighed in shares of J_eq x
# this (the catalog servos' torque limits give their trains 1.2e3 to 1.5e4 rad/s^2)
_HORIZON_MAX = 200  # the horizon key's upper bound (MPCSettings.horizon)
_CROSS_HORIZON_SHARE = 0.9  # a crossing must land within this share of the horizon, and before its last sample
# (_horizon_holds; else the design is refused)
_CROSS_SHARE = 0.25  # a planned crossing accelerates and decelerates the motor with this share of the torque limit
_STANDSTILL_LANDING = 0.05  # at standstill, landings close at most this fraction of landing_velocity
_STANDSTILL_RELEASE = 3.0  # a hold lasts while a slow load stays within this many standstill deadbands
_HANDS_OFF_TORQUE = 0.01  # holding, no torque while the load torque estimate is below this share of N x limit
_HANDS_OFF_LET_GO = 1e-3  # ... and once the plan's torque has come down to this share of the limit
_GATE_PERSIST = 4  # a reading beyond the gate on more samples in a row than this is taken as the truth
_GAP_LIMIT_SHARE = 2.5  # a load reading that puts the gap beyond this many b (plus deflection) is a wrong one ...
_GAP_LIMIT_DEFLECTION = 4.0  # ... plus this many times the mesh's static deflection at the torque limit
_COUNT_PER_STD = math.sqrt(12.0)  # ... plus each reading's error: a count (sqrt(12) quantisation stds) ...
_NOISE_SIGMAS = 6.0  # ... and this many noise stds (a false rejection once in 5e8 readings)
_FAULT_RESTARTS = 3  # this many restarts of the estimate within _FAULT_WINDOW samples latch a fault (zero torque)
_FAULT_WINDOW = 1000
_MISSED_PREDICT = 1000  # missed samples (a motor reading not finite) the estimate is predicted over; after more it
# restarts from the next reading. Taken as one sample, the motion of a missed sample came in as an innovation: one
# miss in every 100 samples of the sine on shing1993_servo, 2.2e-4 rad RMS against 2.9e-6 (now 2.1e-5)
_BRAKE_TIME = 0.02  # after a fault the motor is braked to rest with this time constant [s], then the torque is zero
_BRAKE_REST = 0.1  # ... exactly zero once the motor's reading has not changed for this long [s] (at rest)
_RIGID_SAMPLES = 2.0  # a gap crossed within this many samples (at _CROSS_SHARE of the limit) is designed rigid
_GAP_NOISE_TOL = 3.0  # the contact tolerance is at least this many times the measured gap's noise std
_FLICKER_STD = 24.0  # alternating gap innovations within this many reading stds (7 counts) are an encoder's flicker
_FRICTION_NOISE = 10.0  # the plan ramps the motor's Coulomb friction in over this many noise stds per sample
_STALL_SAMPLES = 5  # a landing due for this many samples more than a crossing lasts has stalled ...
_STALL_SHARE = 0.25  # ... if the gap stopped within this share of the flank
_AT_LIMIT = 0.999999999999  # a planned torque within 1e-12 of the limit is at the QP's bound: the limit exactly
_SMOOTHING_DEFAULT_SHARE = 0.25  # without a smoothing in the file: at most this share of that mesh torque
_SMOOTHING_SHARE = 0.5  # smoothing may be at most this share of the mesh torque the torque limit gives the load
_GOVERNOR_SHARE = 0.25  # the reference governor's profile accelerates and brakes the load with this share of what the
# torque limit leaves after the model's friction and load torque (see *Large steps*)
_GOVERNOR_PASS = 1.0  # the plan is given a jump of the reference as it is where it stops it within its horizon
# (after a crossing) at this share of that acceleration


def _pattern_keys(n: int, n_cross: int, rigid: bool) -> list[tuple[int, int]]:
    """The ``(start of the gap, landing)`` of every condensed QP an MPC of horizon ``n`` builds, in the order it builds
    them (:meth:`MPC._build_patterns`): all in contact first; then every separation ``a`` with a landing up to
    ``n_cross + 2`` samples on; then the landings from a floating start, any countdown. Backlash-free: the first."""
    keys = {(n, n + 1): None}
    if not rigid:
        for a in range(n):
            for e in range(a + 1, a + n_cross + 3):
                keys.setdefault((a, min(e, n + 1)))
        for e in range(1, n + 2):
            keys.setdefault((0, e))
    return list(keys)


def _pattern_count(n: int, n_cross: int, rigid: bool) -> int:
    """How many condensed QPs an MPC of horizon ``n`` builds (:func:`_pattern_keys`)."""
    return len(_pattern_keys(n, n_cross, rigid))


def _pattern_bytes(n: int) -> int:
    """Memory of one condensed QP with its solver data [bytes]: the Hessian and its factor (n x n each), the
    parameter map K (n_p x n_p), per flank the rows A (twice: the pattern's and the solver's C-order copy) and the
    gradient map M; n_p = 2 n + 8. (Measured on a 1:1 pair at horizon 100: 1.36 GB for 1.35 estimated.)"""
    n_p = 2 * n + 8
    return 8 * (2 * n * n + n_p * n_p + 4 * (n + 2) * n + 2 * (2 * n + 2) * n_p)


def _check_pattern_memory(n: int, n_cross: int, rigid: bool, cross_steps: float) -> None:
    """Refuse a design whose condensed QPs would not fit, before they are built: their number grows with the
    horizon times the crossing's samples and each with the horizon squared (a 200-sample horizon at 0.1 ms took
    24 GB and the kernel's out-of-memory kill; at 1 ms on a 1:1 pair, over 4 GB)."""
    need = _pattern_count(n, n_cross, rigid) * _pattern_bytes(n)
    avail = available_memory()
    cap = MAX_OUTPUT_BYTES if avail is None else min(MAX_OUTPUT_BYTES, avail // 2)
    if need <= cap:
        return
    fits = next((h for h in range(n - 1, 0, -1)
                 if _pattern_count(h, 0 if rigid else max(2, _samples(cross_steps, h + 1)), rigid)
                 * _pattern_bytes(h) <= cap), None)
    why = "half the memory available" if cap < MAX_OUTPUT_BYTES else "the cap"
    holds = fits is not None and _horizon_holds(cross_steps, fits)
    ask = f"a horizon of at most {fits} samples fits" if holds else "no horizon that holds a crossing fits"
    raise InputError(f"horizon = {n} samples: the MPC's {_pattern_count(n, n_cross, rigid):,} condensed QPs would take "
                     f"about {need / 1e9:.3g} GB, more than the {cap / 1e9:.3g} GB this run may use ({why}); {ask} "
                     f"(or a longer sample_time, which shortens the crossing in samples)", field="horizon")


def _governor_step(g: float, w: float, rd0: float, r1: float, rd1: float, a: float, a_max: float, v_max: float,
                   Ts: float) -> tuple[float, float]:
    """One sample of the reference governor's profile while it is off the reference (see *Large steps*).

    From the governed angle ``g`` and speed ``w`` at a sample (where the reference's speed is ``rd0``), the governed
    angle and speed at the next one [rad, rad/s], towards the reference ``r1`` that moves on at ``rd1`` from there.
    The profile moves with the reference's own speed change (at most ``a_max - a`` of it per second, so that its
    speed changes by at most ``a_max`` [rad/s^2] in all) and closes on it with the discrete time-optimal profile at
    ``a`` [rad/s^2] in the frame that moves with the reference, at most ``v_max`` fast [rad/s]: braking at ``a``
    from the closing speed ``a Ts m`` covers ``a Ts^2 m (m + 1) / 2`` including this sample's move, hence ``m``;
    within a sample of the reference the profile steps onto it (on a reference at rest the last sample may pass it
    by up to ``a Ts^2 / 8``: the sample before cannot brake quite enough). The exported C
    (``gcx_mpc_governor_step``) does the same arithmetic in the same order.
    """
    E = r1 - g - Ts * rd1  # how far the reference leads, in the frame moving with it
    aT = a * Ts
    e = abs(E)
    m = 0.5 * (math.sqrt(1.0 + 8.0 * e / (aT * Ts)) - 1.0)
    y = math.copysign(min(aT * m, e / Ts), E)  # the closing speed that still stops on the reference
    fT = (a_max - a) * Ts
    y0 = w + min(max(rd1 - rd0, -fT), fT) - rd1  # the closing speed if the profile moved with the reference
    y1 = y0 + min(max(y - y0, -aT), aT)
    w1 = min(max(rd1 + y1, -v_max), v_max)
    return g + Ts * w1, w1


def _clip_torque(u: float, umax: float) -> float:
    """The QP's torque clipped to the limit ``umax``; one at the QP's bound, which holds only to rounding (a few
    ulps either side: the solver's ``x`` recomputed from its factorisation, ``x[0] - f1``), is the limit exactly,
    so that a saturated step can be counted by comparing with the limit (the exported header's word)."""
    u = min(max(u, -umax), umax)
    return math.copysign(umax, u) if abs(u) >= _AT_LIMIT * umax else u


def _samples(steps: float, cap: int) -> int:
    """``ceil(steps)``, at most ``cap`` (also for an infinite or overflowing count, e.g. a torque limit or a
    closing speed near zero)."""
    return cap if not steps < cap else math.ceil(steps)


def _horizon_holds(cross_steps: float, n: int) -> bool:
    """Whether a horizon of ``n`` samples holds a crossing of ``cross_steps`` samples: it lands within
    :data:`_CROSS_HORIZON_SHARE` of the horizon, and its ``ceil(cross_steps)`` samples end before the horizon does,
    so that the plan sees at least one sample on the new flank. (Without the second rule, horizons under 10 could
    end with the crossing's landing: a crossing then never lowered the plan's cost, the plan never crossed, and on
    ``shing1993_servo`` with ``horizon = 5``, a crossing of 4.32 samples, the load ran off to 5.7 rad RMS on the
    sine, every step "ok".)"""
    return cross_steps <= _CROSS_HORIZON_SHARE * n and _samples(cross_steps, n + 1) < n


def _horizon_needed(cross_steps: float) -> int:
    """The shortest horizon that holds a crossing of ``cross_steps`` samples (:func:`_horizon_holds`)."""
    if not math.isfinite(cross_steps) or cross_steps > 1e9:
        return 2**62
    return max(math.ceil(cross_steps / _CROSS_HORIZON_SHARE), math.ceil(cross_steps) + 1)


@dataclasses.dataclass(slots=True)
class _Pattern:
    """Condensed QP data of one mode sequence (separation from sample ``a``, landing at ``e``).

    Per sign ``sig`` of the flank before the crossing, ``M[sig] @ p`` gives at once the gradient ``g``
    (``N``), the lower bounds of the ``N`` mesh-torque rows (``sig F >= 0`` on contact samples), the
    landing-position right-hand side (equality, in units of ``b``) and minus the landing velocity's
    free part (in ``b / Ts``); ``A[sig]`` holds the rows (Fortran order, as CasADi stores dense
    matrices). The constant part of the cost is ``p' K p``.
    """

    H: NDArray[np.float64]
    K: NDArray[np.float64]
    A: dict[int, NDArray[np.float64]]
    M: dict[int, NDArray[np.float64]]
    ptr: dict[int, tuple[int, int]]  # data addresses of H and A[sig] (the compiled solver reads them)
    has_landing: bool
    land_row: int  # mesh-torque row of the first contact sample after the landing (-1: none in the horizon)
    gap_rows: NDArray[np.intp]  # rows that bound the gap (floating samples): -b <= s <= b, width 2 in units of b
    solver_data: Any = None  # what the QP backend prepared for this pattern (a Hessian factor, rows in C order)


class MPC(Controller):
    """Backlash-aware position MPC (mode-switched condensed QP, soft landing, Kalman observer).

    Parameters
    ----------
    info : LoopInfo
        Design-time plant knowledge (inertias, friction, base radii, torque limit, load torque).
    settings : MPCSettings, optional
        Horizon, solver, weights, observer noise, backlash estimate (default: :class:`MPCSettings` with
        the plant's backlash).
    Ts : float
        Sample period [s].
    name : str
        Label.
    compiled : bool, optional
        Force (True) or forbid (False) the compiled QP; default: compiled where a C compiler exists.
    inject_failures : set of int, optional
        Sample indices (counted from :meth:`reset`) at which the solve is reported failed, to exercise
        the fallback.
    reading_error : tuple of float, optional
        The largest error of a motor and of a load encoder reading [rad], which :attr:`gap_limit` allows for:
        a count and six noise stds of each encoder (:func:`build_mpc` gives them from the model's sensors);
        default: a count of an encoder whose quantisation is ``measurement_noise`` (``sqrt(12)`` of it) each.
    load_noise : float, optional
        The load reading's std [rad] for the observer, where it is above ``measurement_noise`` (see *Coarse load
        encoders* in the module docstring; :func:`build_mpc` gives it where a count of the load encoder is over the
        lost motion). Default: ``measurement_noise``.
    load_std : float, optional
        The load reading's own std [rad] (:func:`build_mpc` gives it from the sensors): under a rigid plan the
        centre of inertia is measured with the combination of the encoders of least error (*Coarse load encoders*).
    scaled_smoothing : bool
        ``smoothing`` is the default scaled down to a quarter of the mesh torque the torque limit gives the load
        (:func:`build_mpc`): a design where even that is below the load's friction and load torque is refused.
    progress : callable, optional
        Called with the fraction of the design done (the condensed QPs, one per mode sequence, are most of it:
        about 10 s at a horizon of 100 samples, 80 s at 150).

    Attributes
    ----------
    solve_times : list of float
        Wall time of the QP solves of each step [s] (one entry per step).
    step_times : list of float
        Wall time of each :meth:`step`, observer and bookkeeping included [s].
    statuses : list of str
        Solver status of each step (``"ok"`` or why the solution was rejected).
    fallbacks : list of dict
        ``{"t", "reason"}`` for each step that applied the previous plan's next input, ran without a reading
        (rejected or missing: the plan ran on the prediction) or missed its sample (a non-finite motor
        reading: zero torque).
    reading_gate : tuple of float
        The largest distance [rad] of a motor and of a load encoder reading from the shaft angle predicted
        for it that the observer accepts (see *Readings* in the module docstring).
    gap_limit : float
        The largest gap [m] between the motor and load encoders' readings that the observer takes the load
        reading with (``inf``: no limit); beyond it the motor encoder alone is used (see *Readings*).
    n_cross : int
        Samples a planned crossing of the gap lasts (0 without backlash: nothing to cross).
    rigid_reason : str
        Why the plan is the rigid train's (backlash estimate 0, a gap crossed within two samples, or one below
        the encoders' noise), ``""`` for the gap model.
    fault : str
        Why the controller stopped (see *A fault* in the module docstring), ``""`` while it runs.

    Raises
    ------
    InputError
        For a sample time that is not positive.
    SolverError
        With ``compiled=True`` where the QP cannot be compiled.

    Notes
    -----
    See the module docstring for the model, the choice of a mode-switched QP and the solver path.
    """

    def __init__(self, info: LoopInfo, settings: MPCSettings | None = None, *, Ts: float = 1e-3,
                 name: str = "mpc", compiled: bool | None = None, inject_failures: set[int] | None = None,
                 reading_error: tuple[float, float] | None = None, load_noise: float | None = None,
                 load_std: float | None = None, scaled_smoothing: bool = False,
                 progress: Callable[[float], Any] | None = None) -> None:
        super().__init__()
        info = check_loop_info(info)
        if settings is not None and not isinstance(settings, MPCSettings):
            raise InputError(f"settings = {settings!r} is not an MPCSettings: expected "
                             "gearctl.design.mpc.MPCSettings(horizon=..., ...) or None (the defaults)",
                             field="settings")
        st = settings if settings is not None else MPCSettings()
        # None: the design plant's (see MPCSettings.backlash)
        backlash: float = info.plant.backlash if st.backlash is None else st.backlash
        st = dataclasses.replace(st, backlash=backlash)
        if not (Ts > 0 and math.isfinite(Ts)):
            raise InputError(f"Ts = {Ts!r} is out of range: expected a number > 0 [s]", field="sample_time")
        self.info, self.settings, self.Ts, self.name = info, st, Ts, name
        self.uses_load_encoder = st.feedback == "load"
        self.inject_failures = set(inject_failures or ())
        p = info.plant
        self.N = n = st.horizon
        self.preview = n + 1  # reference samples a step reads: r(t) .. r(t + N Ts)
        self._b = backlash
        self._sigma_load = max(st.measurement_noise, load_noise or 0.0)
        self._load_std = load_std
        self._umax = min(info.torque_limit, 1e6)
        # torques are weighed, and the observer's process noise is stated, as shares of the torque limit; without
        # one, of the torque that accelerates the rigid train at _FREE_ACCELERATION (1 N m had a 14 kg m^2 motor's
        # plan weigh its torque changes 1e8 times too heavily: it could not stop within the horizon and ran away)
        lim = info.torque_limit
        self._u_scale = (max(lim, 1e-9) if math.isfinite(lim) and lim > 0.0
                         else max(info.J_eq * _FREE_ACCELERATION, 1e-9))
        self._tau_load = p.load_torque
        # the motor's Coulomb friction, known from the model, and the speed over which the plan ramps it in: the
        # smooth law's own, and at least what the estimate's noise gives the speed (see *Friction*)
        self._tc1 = p.tc1
        self._w_friction = max(p.coulomb_velocity if p.friction_law is FrictionLaw.SMOOTH else 0.0,
                               _FRICTION_NOISE * st.measurement_noise / Ts)
        self._ratio = info.N
        self._rb1, self._rb2 = p.rb1, p.rb2
        self.model = _gap_model(info, Ts)
        # the load's Coulomb friction, known from the model, in the direction the reference moves (see *Friction*)
        self._tc2 = p.tc2
        # crossing: the lost motion 2b, a quarter of the torque limit accelerating then decelerating the motor alone
        self._a_max = p.rb1 * self._umax / p.J1  # relative acceleration at full torque [m/s^2]
        t_cross = 2.0 * math.sqrt(2 * self._b / (_CROSS_SHARE * self._a_max))
        # contact when |s| >= b - tol; with the load encoder, tol is at least three times the noise of the measured
        # gap (else, with a small b, the reading's noise alone makes contact come and go)
        share_tol = contact_tolerance(info) * backlash
        noise_tol = _GAP_NOISE_TOL * self._gap_reading_std() if st.feedback == "load" else 0.0
        self._tol = max(share_tol, noise_tol)
        # backlash-free (the rigid train, the mesh pushes and pulls): b = 0, or a gap the plan cannot resolve in time
        # (crossed within _RIGID_SAMPLES samples) or the contact bands over half of it: from the encoders' noise, or on
        # a train from the upstream stages' gaps the tolerance takes in (name the one that sets it)
        self.rigid_reason = ("backlash estimate 0" if st.backlash == 0.0 else
                             f"the lost motion is crossed in {t_cross / Ts:.2g} samples at {_CROSS_SHARE:g} x the "
                             f"torque limit (at most {_RIGID_SAMPLES})" if t_cross <= _RIGID_SAMPLES * Ts else
                             "" if self._tol <= 0.5 * backlash else
                             f"the measured gap's noise ({noise_tol / _GAP_NOISE_TOL:.2g} m std, from "
                             f"measurement_noise) is over b / {2 * _GAP_NOISE_TOL:g}" if noise_tol >= share_tol else
                             f"the stages before the last hold {upstream_gap_share(info.nominal):.0%} of the lost "
                             f"motion, which the one-gap plan leaves to its contact tolerance "
                             f"({share_tol / backlash:.2g} b): over half the gap")
        self._rigid = bool(self.rigid_reason)
        # a load encoder too coarse for the gap, under a rigid plan: the centre of inertia from the motor encoder alone
        # (see *Coarse load encoders*)
        self._centre_motor = self._rigid and self._sigma_load > st.measurement_noise
        if not self._rigid and not _horizon_holds(t_cross / Ts, n):
            # a plan that cannot see a crossing through to its landing stays on the near flank and pushes: on a train
            # whose gap takes 21 samples at this torque limit the load ran away (13.5 rad RMS, every step "ok")
            need = _horizon_needed(t_cross / Ts)
            ask = (f"expected horizon >= {need} (a controller file with a longer horizon, or a larger torque_limit; "
                   f"the deadzone_inverse needs none)" if need <= _HORIZON_MAX else
                   f"it needs {need if need < 10**9 else 'more than a billion samples'}, beyond the longest horizon "
                   f"({_HORIZON_MAX}): a larger torque_limit, or the deadzone_inverse, which needs none")
            raise InputError(f"horizon = {n} samples is too short for this plant: a crossing of the lost motion takes "
                             f"{t_cross / Ts:.3g} samples at {_CROSS_SHARE:g} x the torque limit, and the plan must "
                             f"see it land within {_CROSS_HORIZON_SHARE:g} of the horizon and before its last sample; "
                             f"{ask}", field="horizon")
        # a flank is taken where the gap turns back only that far short of b: below the contact tolerance, and
        # on a train also below what the floating intermediate shafts alone leave it short by (the tolerance's
        # share beyond a pair's)
        self._learn_below = backlash - self._tol - (self._tol - 0.02 * backlash)
        held = p.tc2 + abs(p.load_torque)
        if not self._rigid and scaled_smoothing and st.smoothing < held:
            # a load this light for its friction: the landings' push could not move it (fuzzed trains with a
            # 1.7e-10 kg m^2 load under 1 mN m of friction fell back on 83 % of their steps, ISO A 0.65 rad)
            raise InputError(f"the MPC cannot plan landings on this plant: the torque limit gives the load at most "
                             f"{self._mesh_torque_max():.3g} N m of mesh torque as it accelerates the train, below "
                             f"the load's friction and load torque ({held:.3g} N m); use the pid or the "
                             f"deadzone_inverse (a smoothing set in a controller file, at most "
                             f"{_SMOOTHING_SHARE * self._mesh_torque_max():.3g} N m, runs it anyway)",
                             field="smoothing")
        if not self._rigid and st.smoothing > _SMOOTHING_SHARE * self._mesh_torque_max():
            raise InputError(f"smoothing = {st.smoothing:.3g} N m is out of range for this plant: a landing must leave "
                             f"it on the flank, and the torque limit gives the load at most "
                             f"{self._mesh_torque_max():.3g} N m of mesh torque; expected <= "
                             f"{_SMOOTHING_SHARE * self._mesh_torque_max():.3g} N m", field="smoothing")
        # (at most the horizon and one: a crossing the horizon cannot hold is planned as one that ends beyond it)
        self.n_cross = 0 if self._rigid else max(2, _samples(t_cross / Ts, n + 1))
        self.n_lead = self.n_cross // 2
        # the reference governor (see *Large steps*): the load's acceleration the torque limit leaves after the
        # model's friction and load torque, the governed profile's share of it, the jumps of the reference the plan
        # is left to stop alone within its horizon (after a crossing), and the speed at which the viscous friction
        # leaves the profile's share to accelerate
        u_net = self._umax - p.tc1 - (abs(p.load_torque) + p.tc2) / self._ratio
        t_stop = (n - self.n_cross) * Ts
        self._a_net = u_net / (info.J_eq * self._ratio)  # [rad/s^2] at the load
        self._a_gov = _GOVERNOR_SHARE * self._a_net
        self._gov_on = u_net > 0.0 and self._a_gov * Ts * Ts >= 1e-250 and math.isfinite(self._a_gov)
        a_pass = _GOVERNOR_PASS * self._a_net
        self._dv_pass = a_pass * t_stop  # [rad/s] (the profile's lead in speed over the load's estimate)
        self._dp_pass = a_pass * t_stop * t_stop  # [rad]
        self._v_gov = ((1.0 - _GOVERNOR_SHARE) * u_net / (info.d_eq * self._ratio) if info.d_eq > 0.0 and u_net > 0.0
                       else math.inf)  # [rad/s] at the load
        # the readings' gate: along the line of action, what the torque limit can move the motor in one sample
        # (from full torque one way to full the other) plus twice the lost motion (the gap prediction may be off
        # by the whole gap, at an impact, and the backlash estimate by its size); on each shaft [rad], plus twice the
        # reading's own error (a count and the noise: two readings' innovations differ by up to that)
        gate = self._a_max * Ts * Ts + 4.0 * self._b
        e_m, e_l = reading_error if reading_error is not None else (_COUNT_PER_STD * st.measurement_noise,) * 2
        self.reading_gate = (gate / p.rb1 + 2.0 * e_m, gate / p.rb2 + 2.0 * e_l)
        # the gap the two encoders may show (see *Readings*): a few times b, the mesh's deflection under the torque
        # limit and the load torque, the contact tolerance and what the readings' own errors add (a count and the
        # noise of each); none with a backlash estimate of 0
        deflection = (self._mesh_torque_max() + abs(self._tau_load)) / (p.rb2 * p.k) if p.k > 0.0 else math.inf
        self.gap_limit = (_GAP_LIMIT_SHARE * self._b + _GAP_LIMIT_DEFLECTION * deflection + self._tol
                          + p.rb1 * e_m + p.rb2 * e_l if self._b > 0.0 else math.inf)
        # parameter vector p = [z0 (4), tau, p_new, r_1..r_N, r'_N, uff_0..uff_{N-1}, u_prev]
        self._ip_r, self._ip_rd, self._ip_ff, self._ip_u = 6, 6 + n, 7 + n, 7 + 2 * n
        self.n_p = 8 + 2 * n
        _check_pattern_memory(n, self.n_cross, self._rigid, t_cross / Ts)
        self._build_patterns(progress)
        self._build_observer()
        self._qp = _make_qp(n, n + 2, st.solver, compiled)
        for pat in self._patterns.values():
            self._qp.prepare(pat)
        self._qp.lbx[:] = -self._umax
        self._qp.ubx[:] = self._umax
        self._qp.uba[:n] = _INF
        self._bound_landing = st.soft_landing == "bound"
        self._f_land = st.smoothing
        # in the velocity row's units, b / Ts (no landing rows without backlash)
        self._v_land = 0.0 if self._rigid else st.landing_velocity * Ts / backlash
        self._v_land_now = self._v_land  # the bound of the step being solved (smaller at standstill)
        self.statuses: list[str] = []
        self.step_times: list[float] = []
        self.reset()

    def _gap_reading_std(self) -> float:
        """Std of the encoders' gap ``rb1 y1 - rb2 y2`` [m], each reading with its own noise (the same expression as
        before the load's own noise was used where the two are equal: the same last bits)."""
        p, sm, sl = self.info.plant, self.settings.measurement_noise, self._sigma_load
        return sm * math.hypot(p.rb1, p.rb2) if sl == sm else math.hypot(p.rb1 * sm, p.rb2 * sl)

    def _mesh_torque_max(self) -> float:
        """Mesh torque on the load [N m] the torque limit gives the rigid train at rest, without load torque:
        ``J2 N u_max / (N^2 J1 + J2)`` (the share of the motor's torque that accelerates the load)."""
        p, N = self.info.plant, self._ratio
        return p.J2 * N * self._umax / (N * N * p.J1 + p.J2)

    # -- offline: condensing ------------------------------------------------------------------------------
    def _condense(self, a: int, e: int) -> _Pattern:
        """Condensed QP for separation over samples ``a <= k < e`` (landing at state ``e``; ``e > N``: none)."""
        st, m, n, pl = self.settings, self.model, self.N, self.info.plant
        nxi = 6 + n  # coefficients over xi = [z0 (4), tau, p_new, u_0..u_{N-1}]
        Z = np.zeros((4, nxi))
        Z[:, :4] = np.eye(4)
        states, land = [], None
        Fxi = np.zeros((n, nxi))
        Sxi = np.zeros((n, nxi))  # the gap after sample k while floating (kept within the flanks)
        gap = np.zeros(n, dtype=bool)
        for k in range(n):
            sep = a <= k < e
            A, B = (m.A_sep, m.B_sep) if sep else (m.A_con, m.B_con)
            Zprev = Z
            Z = A @ Z
            Z[:, 4] += B[:, 1]
            Z[:, 6 + k] += B[:, 0]
            if k + 1 == e:  # plastic landing: s -> p_new, v -> 0; momentum and load angle kept
                land = Z.copy()
                Z[0] -= m.N * m.kappa2 * Z[2]  # theta2 = phi / N - kappa2 s is continuous
                Z[0, 5] += m.N * m.kappa2
                Z[2:] = 0.0
                Z[2, 5] = 1.0
            elif not sep:  # torque the mesh gives the load over sample k: J2 theta2'' + d2 omega2 - tau (eq 2)
                Fxi[k] = pl.J2 / (m.N * self.Ts) * (Z[1] - Zprev[1]) + pl.d2 / (2 * m.N) * (Z[1] + Zprev[1])
                Fxi[k, 4] -= 1.0
            else:  # floating, not yet landed: -b <= s <= b
                Sxi[k], gap[k] = Z[2], True
            states.append(Z)
        cy = np.array([1 / m.N, 0.0, -m.kappa2, 0.0])  # theta2
        cv = np.array([0.0, 1 / m.N, 0.0, -m.kappa2])  # omega2
        rows_u, rows_p, w = [], [], []

        def split(cx: NDArray) -> tuple[NDArray, NDArray]:
            rp = np.zeros(self.n_p)
            rp[:6] = cx[:6]
            return cx[6:].copy(), rp

        def add(cx: NDArray, weight: float, p_extra: dict[int, float] | None = None,
                u_extra: dict[int, float] | None = None) -> None:
            ru, rp = split(cx)
            for i, v in (p_extra or {}).items():
                rp[i] += v
            for i, v in (u_extra or {}).items():
                ru[i] += v
            rows_u.append(ru)
            rows_p.append(rp)
            w.append(weight)

        zero = np.zeros(nxi)
        for k in range(n):  # load angle against r_{k+1}
            add(cy @ states[k], st.tracking, {self._ip_r + k: -1.0})
        th = 0.5 * n * self.Ts
        add(cy @ states[-1], st.tracking * st.terminal, {self._ip_r + n - 1: -1.0})
        add(th * (cv @ states[-1]), st.tracking * st.terminal, {self._ip_rd: -th})
        for k in range(n):  # u_k - (FF_k - tau / N): torque about the rigid-train feedforward
            add(zero, st.torque / self._u_scale**2, {self._ip_ff + k: -1.0, 4: 1.0 / m.N}, {k: 1.0})
            add(zero, st.torque_rate / self._u_scale**2, {self._ip_u: -1.0} if k == 0 else None,
                {k: 1.0} if k == 0 else {k: 1.0, k - 1: -1.0})
        land_s = land_v = None
        if land is not None:
            if st.soft_landing != "off":  # closing at landing_velocity: sigma_new v = v_L, sigma_new = p_new / b
                add(land[3], st.relative_velocity, {5: -st.landing_velocity / self._b})
            land_s, land_v = split(land[2]), split(land[3])
        Au, Ap, W = np.array(rows_u), np.array(rows_p), np.array(w) * self._cost_scale
        H = 2.0 * (Au.T * W) @ Au
        H = 0.5 * (H + H.T)
        H += 1e-9 * np.trace(H) / n * np.eye(n)  # strictly convex whatever the weights
        G = 2.0 * (Au.T * W) @ Ap
        K = (Ap.T * W) @ Ap
        Hc = np.ascontiguousarray(H)
        A_f, M_f, ptr = {}, {}, {}
        # the gap rows, in units of b: only patterns with a float have any (none without backlash; Sxi = 0 else)
        gb = self._b if gap.any() else 1.0
        for sig in (1, -1):
            sgn = np.where(np.arange(n) < a, sig, -sig).astype(float)
            sgn[np.all(Fxi == 0.0, axis=1)] = 0.0  # separation samples: no mesh torque
            if self._rigid:  # no gap: the mesh pulls as well as pushes, its torque is not constrained
                sgn[:] = 0.0
            Af = np.zeros((n + 2, n))
            Af[:n] = sgn[:, None] * Fxi[:, 6:] + Sxi[:, 6:] / gb  # row k: mesh torque, or the gap / b
            M = np.zeros((2 * n + 2, self.n_p))
            M[:n] = G
            M[n:2 * n, :6] = -sgn[:, None] * Fxi[:, :6] - Sxi[:, :6] / gb  # gap rows: minus s_free / b
            # rows scaled to O(1): the gap in units of b, the speed in b / Ts
            if land_s is not None and land_v is not None:
                Af[n], Af[n + 1] = land_s[0] / self._b, land_v[0] * self.Ts / self._b
                M[2 * n] = -land_s[1] / self._b
                M[2 * n, 5] += 1.0 / self._b  # s at landing = p_new
                M[2 * n + 1] = -land_v[1] * self.Ts / self._b
            A_f[sig], M_f[sig] = np.asfortranarray(Af), np.ascontiguousarray(M)
            ptr[sig] = (Hc.ctypes.data, A_f[sig].ctypes.data)
        return _Pattern(H=Hc, K=np.ascontiguousarray(K), A=A_f, M=M_f, ptr=ptr, has_landing=land_s is not None,
                        land_row=e if e < n else -1, gap_rows=np.flatnonzero(gap))

    def _build_patterns(self, progress: Callable[[float], Any] | None = None) -> None:
        n, nc = self.N, self.n_cross
        self._all_contact = (n, n + 1)
        self._cost_scale = 1.0
        H0 = self._condense(n, n + 1).H
        self._cost_scale = 1.0 / float(np.mean(np.diag(H0)))  # Hessian diagonal ~ 1 for the solver
        # backlash-free: the train is always in contact, no separation or landing patterns
        keys = _pattern_keys(n, nc, self._rigid)
        self._patterns: dict[tuple[int, int], _Pattern] = {}
        for i, key in enumerate(keys):
            self._patterns[key] = self._condense(*key)
            if progress is not None:
                progress((i + 1) / len(keys))

    # -- offline: observer --------------------------------------------------------------------------------
    def _build_observer(self) -> None:
        """Steady-state Kalman gains of the two observers.

        Centre of inertia ``[phi, omega, d]``: the rigid train; impacts conserve momentum, so it is exact in
        every mode where the shafts' viscous friction is in proportion to their inertia (``d1 / J1 = d2 / J2``).
        Otherwise, while the gap is open, the friction differs from the rigid train's by a term in the relative
        speed, which the disturbance estimate ``d`` takes up (on the three-stage catalog train's equivalent pair,
        all its viscous friction on the load, some 3.6e-4 N m during each crossing); measured by
        ``phi_m = (J1 y1 + (J2/N) y2) / J_eq`` (``y1 - kappa1 s`` with the motor encoder alone).
        Gap ``[s, v]``: the separation model, measured by ``s_m = r_b1 y1 - r_b2 y2``; a small gain
        (the model is exact between impacts) and a large one, used when the innovation shows an impact.
        Without backlash there is no gap to estimate (``s = v = 0``) and the gap gains are not designed.
        """
        st, m = self.settings, self.model
        sp = sd = st.process_noise * self._u_scale
        sm = st.measurement_noise
        load = st.feedback == "load"
        Ac = np.eye(3)
        Ac[:2, :2] = m.A_con[:2, :2]
        Ac[:2, 2] = m.B_con[:2, 1]
        Gc = np.zeros((3, 2))
        Gc[:2, 0], Gc[2, 1] = m.B_con[:2, 0], 1.0
        a1, a2 = self.info.plant.J1 / self.info.J_eq, self.info.plant.J2 / (m.N * self.info.J_eq)
        sl = self._sigma_load
        self._c_centre = m.kappa1 if load and not self._centre_motor else 0.0
        if not load:  # the motor encoder alone
            r_phi = sm
        elif self._centre_motor:  # the motor encoder alone, and the gap it reads through (uniform within +-b)
            r_phi = math.sqrt(sm**2 + (m.kappa1 * self._b)**2 / 3.0)
        elif self._rigid and self._load_std is not None and self._load_std != sm:
            # the rigid plan does not track the gap: phi = y1 - c s_m with the c that minimises the error's variance
            # (the gap uniform within +-b, each encoder its own noise; c = kappa1 is the exact centre of inertia)
            # (an exact load reading, no encoder and no noise, is given the least noise, as measurement_noise is
            # without sensors: with no gap either, its error's variance was 0 and the filter's gain singular, a
            # LinAlgError traceback on a fuzzed backlash-free pair without sensors)
            rb1, rb2 = self.info.plant.rb1, self.info.plant.rb2
            vs, v1, v2 = self._b**2 / 3.0, sm**2, (self._load_std or MEASUREMENT_NOISE_FLOOR)**2
            c = (m.kappa1 * vs + rb1 * v1) / (vs + rb1**2 * v1 + rb2**2 * v2)
            self._c_centre = c
            r_phi = math.sqrt((m.kappa1 - c)**2 * vs + (1.0 - c * rb1)**2 * v1 + (c * rb2)**2 * v2)
        else:  # both encoders (the same expression as before where their noises are equal: the same last bits)
            r_phi = sm * math.hypot(a1, a2) if sl == sm else math.hypot(a1 * sm, a2 * sl)
        Lc = _kalman_gain(Ac, Gc, np.diag([sp**2, sd**2]), np.array([[1.0, 0.0, 0.0]]), np.array([[r_phi**2]]))
        self._Lc = tuple(float(v) for v in Lc[:, 0])
        self._centre_rows = tuple(float(v) for v in (Ac[0, 0], Ac[0, 1], Ac[1, 1], m.B_con[0, 0], m.B_con[1, 0],
                                                       m.B_con[0, 1], m.B_con[1, 1]))
        # gap: rows of the separation model (they also see phi, omega through friction)
        self._gap_rows = tuple(float(v) for v in (*m.A_sep[2], *m.B_sep[2], *m.A_sep[3], *m.B_sep[3]))
        r_s = self._gap_reading_std()
        if self._rigid:  # no gap (and no impact: the velocity-jump model below would be degenerate)
            self._Lg = ((0.0, 0.0), (0.0, 0.0))
            self._impact_innovation = math.inf
            self._flicker_innovation = self._flicker_return = 0.0
            return
        Ag, Gg = m.A_sep[2:, 2:], m.B_sep[2:, :1]
        v_small = sp  # unmodelled torque on the motor
        v_big = self._b / self.Ts  # an impact: a velocity jump of the order of b / Ts
        Cg = np.array([[1.0, 0.0]])
        Lg_small = _kalman_gain(Ag, Gg, np.array([[v_small**2]]), Cg, np.array([[r_s**2]]))
        Gv = np.array([[0.0], [1.0]])
        Lg_big = _kalman_gain(Ag, Gv, np.array([[v_big**2]]), Cg, np.array([[r_s**2]]))
        self._Lg = ((float(Lg_small[0, 0]), float(Lg_small[1, 0])), (float(Lg_big[0, 0]), float(Lg_big[1, 0])))
        self._impact_innovation = 5.0 * r_s + 1e-3 * self._b
        self._flicker_innovation = _FLICKER_STD * r_s  # about 7 counts of quantised encoders (a count: 3.5 std)
        self._flicker_return = 2.0 * r_s  # a flickering reading comes back to within this of where it was [m]

    # -- online --------------------------------------------------------------------------------------------
    def reset(self) -> None:
        """Forget the estimate, the plan, the flank schedule and the recorded statistics."""
        n = self.N
        self.solve_times, self.fallbacks, self.statuses, self.step_times = [], [], [], []
        self.overruns = 0
        self._z: NDArray[np.float64] | None = None  # observer state [phi, omega, s, v, d]
        self._flanks = [self._b, self._b]  # where the back (index 0) and front (1) flanks are, |s| [m]
        self._stall = [0.0, 0.0]  # where a landing stalled on each side, |s| [m] (0: none; see *Stalled landings*)
        self._overdue = 0  # samples in a row a landing has been due and the gap still floats
        self._base = [self._b, self._b]  # the flanks without the stalls, |s| [m]
        self._reach = [0.0, 0.0]  # the furthest the measured gap has been on each side, |s| [m]
        self._revisits = [0, 0]  # samples since then that came back within tol of it
        self._u = 0.0
        self._f2 = 0.0  # the load's Coulomb friction the observer predicts the next sample with [N m]
        self._dir = 0.0  # the direction of the reference's last motion (0 before any)
        self._f1 = 0.0  # the motor's Coulomb friction torque the last step planned with [N m] (see *Friction*)
        self._plan = np.zeros(n)
        self._lam = np.zeros(n)
        self._keep = (np.zeros(n), np.zeros(n), np.zeros(n + 2))  # a solution set aside while another is tried
        self._flank = 0  # target flank: +1 front, -1 back, 0 undecided
        self._gap_bounded = True  # whether the QP's upper row bounds hold a pattern's gap rows
        self._land: int | None = None
        self._held = False  # holding at standstill (see _holding)
        self._rejects = 0  # samples in a row whose readings the gate rejected
        self._inn = [0.0, 0.0]  # the last accepted readings' innovations, motor and load [rad]
        self._gap_inn = self._gap_inn2 = 0.0  # the floating gap's last two innovations [m] (0 in contact; _observe)
        self._gap_s = (math.nan, math.nan)  # the floating gap's last two readings [m] (NaN in contact)
        self._restarts = [-_FAULT_WINDOW] * _FAULT_RESTARTS  # the samples of the last restarts of the estimate
        self._n_obs = 0  # samples observed (finite motor readings)
        self.fault = ""  # why the controller stopped (braking, then zero torque, until reset), "" while it runs
        self._brake = [0.0, 0, 0.0, 0.0]  # after a fault: last motor reading, its sample, its step, the speed [rad/s]
        self._k = 0
        self._k_run = 0  # the sample after the last step that ran (missed samples do not run; see _predict_missed)
        self._p = np.zeros(self.n_p)
        self._ref: ReferenceLike | None = None
        self._blk_t0 = 0.0
        self._blk_len = 0
        self._gov: tuple[float, float, bool] | None = None  # the governor at t: angle, speed, on the reference
        self._qp.reset()  # the solver's own state too (OSQP's workspace): a reused MPC runs as a new one

    def _preview(self, t: float, ref: ReferenceLike) -> int:
        """Index of ``t`` in the cached reference block (recomputed every few hundred samples)."""
        n = self.N
        if ref is self._ref:
            k = round((t - self._blk_t0) / self.Ts)
            if 0 <= k <= self._blk_len - n - 2 and abs(self._blk_t0 + k * self.Ts - t) <= 1e-9 * max(1.0, abs(t)):
                return k
        self._ref, self._blk_t0 = ref, t
        self._blk_len = 512 + n + 2
        tt = t + self.Ts * np.arange(self._blk_len)
        # (a ReferenceLike may give a constant as a scalar, as the other controllers, which read one sample, allow)
        parts = [np.asarray(v, dtype=float) for v in ref.at(tt)]
        try:
            r, rd, rdd = (np.broadcast_to(v, tt.shape) for v in parts)
        except ValueError:
            raise InputError(f"reference: at(t) of {tt.size} times gave (r, r', r'') of shapes "
                             f"{', '.join(str(v.shape) for v in parts)}; expected arrays of t's shape ({tt.size},) "
                             f"or scalars", field="reference") from None
        info = self.info
        self._R, self._Rd, self._Rdd = r, rd, rdd
        self._FF = FF = self._ratio * (info.J_eq * rdd + info.d_eq * rd)  # rigid-train torque, without the load
        # the reference governor: the samples k -> k + 1 the plan is given as they are (a jump of the angle beyond
        # what the reference's speeds explain that the plan stops alone within its horizon, and an acceleration the
        # torque limit gives; a jump of the speed is the plan's: see *Large steps*), counted so that a window is
        # checked at once
        ok = ((np.abs(r[1:] - r[:-1] - 0.5 * self.Ts * (rd[:-1] + rd[1:])) <= self._dp_pass)
              & (np.abs(rdd[1:]) <= self._a_net))
        self._gov_ok = ok
        self._gov_bad = np.concatenate(([0], np.cumsum(~ok)))
        # per sample i, the preview the parameter vector needs: r_{i+1..i+N}, r'_{i+N}, FF_{i..i+N-1}
        L = self._blk_len - n - 1
        win = np.empty((L, 2 * n + 1))
        sw = np.lib.stride_tricks.sliding_window_view
        win[:, :n] = sw(r[1:], n)[:L]
        win[:, n] = rd[n:n + L]
        win[:, n + 1:] = sw(FF, n)[:L]
        self._win = win
        return 0

    def _load_estimate(self, z: NDArray[np.float64]) -> tuple[float, float]:
        """The load's angle and speed [rad, rad/s] from the observer's state ``z = [phi, omega, s, v, d]``."""
        m = self.model
        return float(z[0]) / m.N - m.kappa2 * float(z[2]), float(z[1]) / m.N - m.kappa2 * float(z[3])

    def _governed(self, i: int, z: NDArray[np.float64]) -> tuple[NDArray, NDArray, NDArray] | None:
        """The reference governor (see *Large steps*): the reference the plan is given over the preview.

        ``None`` where it is the reference itself over the whole preview (the governor on the reference, every
        sample ``k -> k + 1`` of the preview one the plan is given as it is); else the governed angle, speed (samples
        ``0..N``) and acceleration (``0..N-1``) [rad, rad/s, rad/s^2]. Off the reference, the profile follows
        :func:`_governor_step`; it is back on the reference at the sample where it is within ``a Ts^2`` and ``a Ts`` of
        it (and the reference's acceleration is one the torque limit gives). Advances the governor by one sample.
        """
        if not self._gov_on:
            return None
        n, Ts = self.N, self.Ts
        R, Rd, Rdd = self._R, self._Rd, self._Rdd
        if self._gov is None:  # the first sample: on the reference if the plan can take its angle from the load's
            # estimate (a reference that starts in motion, as the sine does, is the plan's to catch)
            th2, om2 = self._load_estimate(z)
            on = abs(float(R[i]) - th2) <= self._dp_pass and abs(float(Rdd[i])) <= self._a_net
            self._gov = (float(R[i]), float(Rd[i]), True) if on else (th2, om2, False)
        g, w, on = self._gov
        if on and self._gov_bad[i + n] == self._gov_bad[i]:  # the reference as it is over the whole preview
            return None
        if on:  # (the reference at t as this step reads it)
            g, w = float(R[i]), float(Rd[i])
        else:  # off the reference: at most what the plan stops within its horizon ahead of the load's estimate
            th2, om2 = self._load_estimate(z)
            g = min(max(g, th2 - self._dp_pass), th2 + self._dp_pass)
            w = min(max(w, om2 - self._dv_pass), om2 + self._dv_pass)
        # back on the reference within what the plan takes in a sample at the torque limit
        a, aTT, aT = self._a_gov, self._a_net * Ts * Ts, self._a_net * Ts
        gr, gd, gdd = np.empty(n + 1), np.empty(n + 1), np.empty(n)
        gr[0], gd[0] = g, w
        ok = self._gov_ok
        for k in range(n):
            j = i + k
            w0 = w
            if on and ok[j]:
                g, w = float(R[j + 1]), float(Rd[j + 1])
                gdd[k] = Rdd[j]
            else:
                g, w = _governor_step(g, w, float(Rd[j]), float(R[j + 1]), float(Rd[j + 1]), a, self._a_net,
                                      self._v_gov, Ts)
                on = (abs(g - float(R[j + 1])) <= aTT and abs(w - float(Rd[j + 1])) <= aT
                      and abs(float(Rdd[j + 1])) <= self._a_net)
                if on:  # back on the reference
                    g, w = float(R[j + 1]), float(Rd[j + 1])
                gdd[k] = (w - w0) / Ts
            gr[k + 1], gd[k + 1] = g, w
            if k == 0:
                self._gov = (g, w, on)
        return gr, gd, gdd

    def _observe(self, y_motor: float, y_load: float | None) -> str | None:
        """Update ``self._z = [phi, omega, s, v, d]`` from the encoders (scalar arithmetic: 5 states).

        Returns why a reading was not used (a fallback to report), else None. A load reading not finite or
        beyond :data:`INPUT_LIMIT` is a missing one: the motor encoder alone updates the estimate, as with
        ``feedback = "motor"``. A finite reading whose innovation (the reading minus the predicted shaft angle)
        differs from the last accepted reading's by more than :attr:`reading_gate` is rejected: the estimate is
        the prediction alone on that sample. A reading
        rejected on more than :data:`_GATE_PERSIST` samples in a row is taken as the truth: the estimate
        restarts from it, as on the first sample (speeds and disturbance zero).
        """
        m, b, tol = self.model, self._b, self._tol
        load = y_load is not None and self.uses_load_encoder
        note = None
        # a missing load reading (also NaN): the motor encoder alone
        if load and y_load is not None and not abs(y_load) <= INPUT_LIMIT:
            load, note = False, "load reading missing (not finite or beyond 1e12 rad): motor encoder alone"
        s_m = float(self._rb1 * y_motor - self._rb2 * y_load) if load else 0.0
        if load and not abs(s_m) <= self.gap_limit:  # the encoders disagree beyond any gap: the load reading is wrong
            note = (f"load reading inconsistent with the motor's (a gap of {s_m:.3g} m beyond gap_limit "
                    f"{self.gap_limit:.3g} m): motor encoder alone")
            load, s_m = False, 0.0
        if self._z is None:  # first sample: at rest, the gap from the encoders (mid-gap without them)
            self._inn = [0.0, 0.0]
            self._gap_inn = self._gap_inn2 = 0.0
            self._gap_s = (math.nan, math.nan)
            phi_m = y_motor - m.kappa1 * s_m
            self._z = np.array([phi_m, 0.0, 0.0 if self._rigid else s_m, 0.0, 0.0])
            return note
        z = self._z
        d = float(z[4])
        phi_p, om_p, s_p, v_p = self._prediction(z)
        # the gate: how far the readings are from the shaft angles the prediction puts them at, against how far the
        # last accepted ones were (a prediction that drifts off under a load step the estimate has not yet followed
        # moves the innovation a little every sample; a wild reading moves it at once)
        # (the gap where the readings put it: within the flanks, where the mesh holds it, and none for the rigid
        # plan; the free prediction alone, pushed by a load torque on a light load, ran 1000 b past a flank in a
        # sample and had every reading refused)
        g1, g2 = self.reading_gate
        s_g = 0.0 if self._rigid else min(max(s_p, -b), b)
        inn1 = y_motor - (phi_p + m.kappa1 * s_g)
        inn2 = (y_load - (phi_p / m.N - m.kappa2 * s_g)) if load and y_load is not None else self._inn[1]
        bad = not abs(inn1 - self._inn[0]) <= g1
        if load and not abs(inn2 - self._inn[1]) <= g2:
            bad = True
        if not bad:
            self._inn[0], self._inn[1] = inn1, inn2
        if bad:
            self._rejects += 1
            if self._rejects > _GATE_PERSIST:  # a reading that persists is the truth: start again from it
                self._rejects = 0
                self._z = None
                self._observe(y_motor, y_load if load else None)
                # restarting again and again: the readings do not follow any motion the model allows (an encoder
                # too coarse for the torque limit, a broken one): stop, rather than drive on predictions
                del self._restarts[0]
                self._restarts.append(self._n_obs)
                if self._n_obs - self._restarts[0] < _FAULT_WINDOW:
                    self.fault = (f"fault: the estimate restarted {_FAULT_RESTARTS} times within "
                                  f"{self._n_obs - self._restarts[0] + 1} samples (the readings follow no motion the "
                                  f"model allows: encoders too coarse, or broken): zero torque from now on")
                return "reading far from the prediction on more than 4 samples: estimate restarted from it"
            self._predict_alone(z, phi_p, om_p, s_p, v_p)
            return "reading rejected (beyond reading_gate of the prediction): estimate predicted"
        self._rejects = 0
        if self._rigid:  # no gap: the rigid train (the mesh deflection F / k is below the encoders' resolution)
            s_n, v_n = 0.0, 0.0
        elif load:
            side = 1 if s_m > 0.0 else -1
            fl = self._flanks[side > 0]
            # the flank is where the gap turns back: the furthest the gap has been on this side, once it has come
            # back there (within tol) on a later sample. A backlash estimate that is too large is corrected by it
            # (the gap never reaches b - tol); the furthest point only grows, so a flank learned short of the
            # true one moves out when the gap goes further
            k = side > 0
            a_s = abs(s_m)
            if a_s > self._reach[k]:
                self._reach[k], self._revisits[k] = a_s, 0
            elif a_s >= self._reach[k] - tol:
                self._revisits[k] += 1
            if self._reach[k] >= self._learn_below:  # the gap reached the flank the estimate puts there
                fl = self._flanks[k] = b
            elif self._revisits[k] >= 2 and self._reach[k] > 0.5 * b:
                fl = self._flanks[k] = self._reach[k]
            self._base[k] = fl
            if self._stall[k] > 0.0:  # a landing stalled there (see *Stalled landings*), until the gap goes further
                if a_s > self._stall[k] + tol:
                    self._stall[k] = 0.0
                else:
                    fl = self._flanks[k] = min(fl, self._stall[k])
            if abs(s_m) >= fl - tol:  # contact: the reduced model's plastic impact
                s_n, v_n = s_m, 0.0
                self._gap_inn = self._gap_inn2 = 0.0
                self._gap_s = (math.nan, math.nan)
            else:
                inn = s_m - s_p
                # a large innovation is an impact (the gap's speed jumped), unless it is an encoder's flicker: the
                # reading back where it was two samples ago (within two reading stds), and the third large innovation
                # in a row, each of the other sign than the one before, none beyond a few counts of the gap reading.
                # The impact gain took each flicker for an impact (a load encoder flickering by 2 counts on every
                # other sample: 0.28 rad RMS on the sine, every status ok). Bounces move the reading on: plain runs
                # keep their figures to the bit
                big = abs(inn) > self._impact_innovation
                g1, g2, lim = self._gap_inn, self._gap_inn2, self._flicker_innovation
                flicker = (abs(s_m - self._gap_s[1]) <= self._flicker_return
                           and inn * g1 < 0.0 and g1 * g2 < 0.0 and min(abs(g1), abs(g2)) > self._impact_innovation
                           and max(abs(inn), abs(g1), abs(g2)) <= lim)
                impact = big and not flicker
                self._gap_inn2, self._gap_inn = self._gap_inn, inn
                self._gap_s = (s_m, self._gap_s[0])
                lg = self._Lg[1] if impact else self._Lg[0]
                s_n, v_n = s_p + lg[0] * inn, v_p + lg[1] * inn
        else:  # motor encoder alone: the gap is predicted, and pinned at the flank it reaches
            s_n, v_n = s_p, v_p
            fl = self._flanks[s_n > 0.0]
            if abs(s_n) >= fl - tol:
                s_n, v_n = math.copysign(fl, s_n), 0.0
        phi_meas = (y_motor - m.kappa1 * s_n) if not load else (y_motor - self._c_centre * s_m)
        inn = phi_meas - phi_p
        l0, l1, l2 = self._Lc
        z[0], z[1], z[2], z[3], z[4] = phi_p + l0 * inn, om_p + l1 * inn, s_n, v_n, d + l2 * inn
        return note

    def _predict_missed(self, n: int) -> None:
        """Carry the estimate over ``n`` missed samples (motor readings not finite or beyond the limit).

        The prediction alone, as for a rejected reading in :meth:`_observe`, the gap pinned at the flank it
        reaches: over the first with the torque of the last step that ran, over the others with the zero torque the
        missed steps returned, which then is the last torque. Over more than :data:`_MISSED_PREDICT` samples the
        estimate restarts from the next reading instead, as on the first sample.
        """
        if n > _MISSED_PREDICT:
            self._z = None
            return
        z = self._z
        assert z is not None
        for _ in range(n):
            self._predict_alone(z, *self._prediction(z))
            self._u = 0.0

    def _prediction(self, z: NDArray[np.float64]) -> tuple[float, float, float, float]:
        """The estimate one sample on, ``(phi, omega, s, v)``, under the torque that acted on the motor (the drive's
        last and its friction) and the load torque: the gap with the separation model, the centre of inertia as the
        rigid train (any mode)."""
        u = self._u + self._f1
        phi, om, s, v, d = z.tolist()
        tau = self._tau_load + d + self._f2
        a0, a1, a2, a3, b0, b1, c0, c1, c2, c3, d0, d1 = self._gap_rows
        s_p = a0 * phi + a1 * om + a2 * s + a3 * v + b0 * u + b1 * tau
        v_p = c0 * phi + c1 * om + c2 * s + c3 * v + d0 * u + d1 * tau
        k00, k01, k11, kb0, kb1, e0, e1 = self._centre_rows
        phi_p = k00 * phi + k01 * om + kb0 * u + e0 * tau
        om_p = k11 * om + kb1 * u + e1 * tau
        return phi_p, om_p, s_p, v_p

    def _predict_alone(self, z: NDArray[np.float64], phi_p: float, om_p: float, s_p: float, v_p: float) -> None:
        """Set the estimate ``z`` to the prediction alone (no reading used): the gap pinned at the flank it reaches
        (as without a load encoder), none for the rigid plan; the disturbance kept."""
        if self._rigid:
            s_n, v_n = 0.0, 0.0
        else:
            s_n, v_n = s_p, v_p
            if abs(s_n) >= self._b - self._tol:
                s_n, v_n = math.copysign(self._b, s_n), 0.0
        z[0], z[1], z[2], z[3] = phi_p, om_p, s_n, v_n

    def _brake_torque(self, y_motor: float) -> float:
        """Torque after a fault [N m]: the motor's speed from the changes of its reading alone (the estimate is not
        trusted), braked with the time constant :data:`_BRAKE_TIME`; zero once the reading stops changing.

        The speed is the last change of the reading over the samples it took, if the change before was in the
        same direction (else the shaft turned round at a count's edge: zero); while the reading stands still it
        is at most that change over the samples since (so it decays to zero at rest). A reading that keeps
        jumping (a broken encoder) keeps the brake acting on what it reads, within the torque limit: a cap at the
        lowest speed measured since the fault was tried and not taken, since a load torque that drives the motor
        then ran it away (227 rad/s against 3 rad/s with the damping).
        """
        y0, k0, dy, w = self._brake
        n = self._n_obs
        if n == self._restarts[-1]:  # the sample of the fault: the reading's origin
            y0, k0, dy, w = y_motor, n, 0.0, 0.0
        elif y_motor != y0:  # a change in the direction of the last one: a speed; else it turned at an edge
            w = (y_motor - y0) / ((n - k0) * self.Ts) if (y_motor - y0) * dy > 0.0 else 0.0
            dy, y0, k0 = y_motor - y0, y_motor, n
        elif (n - k0) * self.Ts >= _BRAKE_REST:  # still for _BRAKE_REST: at rest (a 1/n tail of uN m lasted seconds)
            w = 0.0
        else:  # what the braking leaves of it, and at most the last change over the samples since
            w = math.copysign(min(abs(w) * (1.0 - self.Ts / _BRAKE_TIME), abs(dy) / ((n - k0) * self.Ts)), w)
        self._brake[:] = (y0, k0, dy, w)
        return min(max(-self.info.J_eq * w / _BRAKE_TIME, -self._umax), self._umax) + 0.0  # + 0.0: never -0.0

    def _planned_load_friction(self, i: int, rd: NDArray[np.float64] | None = None) -> float:
        """The load's Coulomb friction over the horizon [N m] (see *Friction*): the mean of ``-T_c2 sgn`` over the
        previewed reference ``r'_{i+1..i+N}``, where ``sgn`` is the sign of ``r'`` or, where the reference rests, of
        its last motion (the friction that held the load when it stopped). Also sets the friction the observer
        predicts the next sample with, that of ``r'_i``. ``rd``: the governed speeds from sample ``i`` on (default:
        the reference's)."""
        if self._tc2 == 0.0:
            return 0.0
        rd = self._Rd if rd is None else rd
        d = self._dir = (1.0 if rd[i] > 0.0 else -1.0) if rd[i] != 0.0 else self._dir
        self._f2 = -self._tc2 * d
        total = 0.0
        for k in range(i + 1, i + 1 + self.N):
            if rd[k] != 0.0:
                d = 1.0 if rd[k] > 0.0 else -1.0
            total += d
        return -self._tc2 * total / self.N

    def _motor_friction(self, z: NDArray[np.float64]) -> float:
        """The model's Coulomb friction torque on the motor at the estimated motor speed [N m] (see *Friction*)."""
        if self._tc1 == 0.0:
            return 0.0
        w1 = float(z[1]) + self.model.kappa1 * float(z[3])
        return -self._tc1 * min(max(w1 / self._w_friction, -1.0), 1.0)

    def _holding(self, i: int, z: NDArray[np.float64], gov: tuple[NDArray, NDArray, NDArray] | None = None) -> bool:
        """Whether the plan holds at standstill (see *Standstill* in the module docstring).

        True while the previewed reference rests, the load is slow (its speed would not take it a deadband
        further within the horizon) and within ``standstill_deadband`` of the reference; once holding, within
        :data:`_STANDSTILL_RELEASE` deadbands. A hold does not start during a landing planned in motion (its
        landing-speed bound would shrink under it). Updates the hold flag.
        """
        n = self.N
        if gov is None:
            win = self._win[i]
            r = self._R[i]
            moves = win[n] != 0.0 or not (win[:n] == r).all()
        else:  # the governed reference (see *Large steps*)
            r = gov[0][0]
            moves = gov[1][n] != 0.0 or not (gov[0][1:] == r).all()
        if moves:
            self._held = False
            return False
        if not self._held and self._land is not None:  # a landing under way is finished first
            return False
        theta2, omega2 = self._load_estimate(z)
        band = self.settings.standstill_deadband
        slow = abs(omega2) * (n * self.Ts) <= band
        if self._held:
            band = _STANDSTILL_RELEASE * band
        self._held = slow and abs(r - theta2) <= band
        return self._held

    def _steps_to_land(self, s: float, flank: int, torque_share: float | None = None) -> int:
        """Samples to close the gap to ``flank`` from ``s``, accelerating then decelerating."""
        dist = max(self._flanks[flank > 0] - flank * s, 0.0)
        t = 2.0 * math.sqrt(dist / ((torque_share or _CROSS_SHARE) * self._a_max))
        return max(1, _samples(t / self.Ts, self.N))

    def _solve(self, key: tuple[int, int], p_new: float, sig: int, cost: bool = False) -> tuple[str, float, float]:
        """Solve the QP of pattern ``key`` (flank ``sig`` before any crossing).

        Returns the status, the solve time [s] and, with ``cost``, the full cost (QP cost plus the
        constant part; ``inf`` if the solve failed).
        """
        pat = self._patterns[key]
        p, qp, n = self._p, self._qp, self.N
        p[5] = p_new
        qp.form(pat, sig, p)
        lba, uba = qp.lba, qp.uba
        if self._rigid:  # the mesh-torque rows are empty: no bound (the mesh pulls as well as pushes)
            lba[:n] = -_INF
        if self._gap_bounded:  # undo the last pattern's gap rows
            uba[:n] = _INF
            self._gap_bounded = False
        if pat.gap_rows.size:  # -b <= s <= b: in units of b, -1 - s_free / b <= row <= 1 - s_free / b
            g_rows = pat.gap_rows
            uba[g_rows] = lba[g_rows] + 1.0
            lba[g_rows] -= 1.0
            self._gap_bounded = True
        if pat.land_row >= 0 and self._v_land_now == self._v_land:  # land onto a loaded flank: the impacts then
            lba[pat.land_row] += self._f_land  # die out instead of re-landing (not at standstill: it would push)
        if pat.has_landing:
            uba[n] = lba[n]
            if self._bound_landing:  # closing, at most landing_velocity: 0 <= sigma v <= v_L
                c = lba[n + 1]
                v_l = self._v_land_now
                uba[n + 1] = c + (v_l if p_new > 0.0 else 0.0)
                lba[n + 1] = c - (0.0 if p_new > 0.0 else v_l)
            else:
                lba[n + 1], uba[n + 1] = -_INF, _INF
        else:
            lba[n] = lba[n + 1] = -_INF
            uba[n] = uba[n + 1] = _INF
        qp.use(pat, sig)
        # Python's cyclic collector is paused for the call (and restored at once): a collection triggered by
        # the few objects the call allocates would otherwise land inside the solve (4-8 ms on the benchmark
        # machine); it runs at the next allocation instead, in the step overhead that step_times measures
        collect = gc.isenabled()
        gc.disable()
        t0 = time.perf_counter()
        status = qp.solve()
        dt = time.perf_counter() - t0
        if collect:
            gc.enable()
        return status, dt, (self._full_cost(key) if cost else 0.0)

    def _full_cost(self, key: tuple[int, int]) -> float:
        """Full cost of the solution in the QP buffers for pattern ``key`` (``inf`` if it failed)."""
        if not self._qp.kkt[0] <= self._qp.tol:
            return math.inf
        p = self._p
        return float(self._qp.cost[0]) + float(p @ (self._patterns[key].K @ p))

    def _land_on(self, flank: int, e: int, s: float) -> tuple[str, float, float, tuple[int, int]]:
        """Solve the landing on ``flank`` after ``e`` samples (later if that is infeasible).

        Returns the status, the solve time [s], the full cost and the pattern used.
        """
        n = self.N
        key = (0, min(max(e, 1), n + 1))
        # the force rows take the sign of the flank *before* a crossing: for a landing, -flank
        target = flank * self._flanks[flank > 0]
        status, dt, cost = self._solve(key, target, -flank, True)
        if status != "ok" and key[1] <= n:  # infeasible (the velocity bound): land later
            key = (0, min(key[1] + self._steps_to_land(s, flank, 0.5), n + 1))
            status, dt2, cost = self._solve(key, target, -flank, True)
            dt += dt2
        return status, dt, cost, key

    def _set_aside(self) -> None:
        x, lx, la = self._keep
        x[:], lx[:], la[:] = self._qp.x, self._qp.lam_x, self._qp.lam_a

    def _restore(self) -> None:
        x, lx, la = self._keep
        self._qp.x[:], self._qp.lam_x[:], self._qp.lam_a[:] = x, lx, la

    def step(self, t: float, y_motor: float, y_load: float | None, ref: ReferenceLike) -> float:
        """Motor torque for sample time ``t`` [N m] (see :class:`~gearctl.design.base.Controller`).

        Parameters
        ----------
        t : float
            Sample time [s].
        y_motor : float
            Motor encoder reading, motor angle ``theta1`` [rad].
        y_load : float or None
            Load encoder reading ``theta2`` [rad], or None without a load encoder.
        ref : ReferenceLike
            The load-angle reference; its ``at`` is called with an array of the next few hundred sample times
            (the horizon's preview) and must give ``(r, r', r'')`` of that shape, or scalars.

        Returns
        -------
        float
            The motor torque held over the sample [N m] (0 for a missed motor reading).

        Raises
        ------
        InputError
            For a reference whose ``at`` gives arrays of another shape (field ``reference``).

        Notes
        -----
        In contact on the target flank the QP that stays on that flank is solved first. If its
        mesh-torque constraint binds somewhere in the horizon (the plan would pull on the flank), the QP
        of a crossing centred there is solved too and the cheaper plan (full cost) is applied; a crossing
        that starts now is then committed. Floating (start-up, a bounce, a crossing) the QP of the
        landing pattern is solved, with a longer landing if that one is infeasible. Without backlash
        (``backlash = 0``) only the rigid-train QP is solved, with the mesh torque unconstrained. At standstill
        the rules of *Standstill* in the module docstring apply (no flank change, one-sided targets, no torque
        on a free load). The entry in :attr:`solve_times` is the step's total QP time.

        A ``y_motor`` not finite or beyond :data:`INPUT_LIMIT` is a missed sample, as in the exported API: the
        torque is 0, the estimate and the plan stay as they were, and the step is recorded in :attr:`fallbacks`;
        the next step that runs predicts the estimate over it first (:meth:`_predict_missed`).
        A missing (not finite, or beyond the limit) or wild load reading, or a wild motor reading within the limit,
        is handled by the observer (*Readings*).
        """
        t_step = time.perf_counter()
        n = self.N
        i = self._preview(t, ref)
        if not abs(y_motor) <= INPUT_LIMIT:  # a missed sample (as the exported API): zero torque, state unchanged
            self._k += 1
            self.solve_times.append(0.0)
            self.statuses.append("fault" if self.fault else "bad input")  # the latched fault is said on every step
            self.fallbacks.append({"t": float(t), "reason": "motor reading not finite or beyond 1e12 rad: zero torque, "
                                                            "state unchanged"})
            self.step_times.append(time.perf_counter() - t_step)
            return 0.0
        if self._z is not None and not self.fault and self._k > self._k_run:
            self._predict_missed(self._k - self._k_run)
        self._k_run = self._k + 1
        self._n_obs += 1
        note = self._observe(y_motor, y_load) if not self.fault else None
        if self.fault:  # latched (see *Readings*): the motor braked to rest, reported on every step
            u = self._brake_torque(y_motor)
            self._k += 1
            self._u = u
            self._plan[:] = 0.0
            self.solve_times.append(0.0)
            self.statuses.append("fault")
            self.fallbacks.append({"t": float(t), "reason": self.fault})
            self.step_times.append(time.perf_counter() - t_step)
            return u
        z = self._z
        assert z is not None  # _observe set it (a latched fault returned above)
        gov = self._governed(i, z)  # the reference the plan is given (see *Large steps*)
        tau = self._tau_load + float(z[4]) + self._planned_load_friction(*((i,) if gov is None else (0, gov[1])))
        # the QP sees angles from an origin, the reference at t: its data do not grow with the absolute angle
        # (at 1e4 rad a double's spacing is 1.8e-12 rad; the QP's gradient would otherwise sum terms of the size of
        # the angle times the tracking weight, which cancel), so a run at any offset equals the run at zero
        origin = float(self._R[i]) if gov is None else float(gov[0][0])
        p = self._p
        p[:4] = z[:4]
        p[0] = float(z[0]) - self._ratio * origin
        p[4] = tau
        if gov is None:
            p[6:7 + 2 * n] = self._win[i]  # r_1..r_N, r'_N, FF_0..FF_{N-1}
        else:
            gr, gd, gdd = gov
            p[6:6 + n] = gr[1:]
            p[6 + n] = gd[n]
            p[7 + n:7 + 2 * n] = self._ratio * (self.info.J_eq * gdd + self.info.d_eq * gd[:n])
        p[6:6 + n] -= origin
        qp = self._qp
        qp.x0[:-1] = self._plan[1:]  # warm start: the previous plan, shifted
        qp.x0[-1] = self._plan[-1]
        qp.lam_x0[:-1] = self._lam[1:]
        qp.lam_x0[-1] = 0.0
        s = float(z[2])
        b_hi, b_lo = self._flanks[True], self._flanks[False]
        side = 1 if s >= b_hi - self._tol else (-1 if s <= -(b_lo - self._tol) else 0)
        sig = self._flank
        if sig == 0:  # first sample: in contact, or floating (both flanks are then tried, front first)
            self._flank = sig = side or 1
        if side == 0 and self._land is not None and self._land <= 1 and self.uses_load_encoder:  # due, floating
            self._overdue += 1
            k = sig > 0
            if (self._overdue > self.n_cross + _STALL_SAMPLES
                    and 0.0 <= self._base[k] - sig * s <= _STALL_SHARE * self._base[k]):
                # stalled short of the flank (see *Stalled landings*): contact is where the gap stopped
                self._stall[k] = self._flanks[k] = sig * s
                side, self._overdue = sig, 0
        else:
            self._overdue = 0
        hold = not self._rigid and self._holding(i, z, gov)
        # the QP plans the torque that acts on the motor, the drive's plus the model's Coulomb friction there
        # (constant over the horizon; see *Friction*): its bounds, and the last torque, move with the friction
        f1 = 0.0 if hold else self._motor_friction(z)
        self._f1 = f1
        p[self._ip_u] = self._u + f1
        qp.lbx[:] = f1 - self._umax
        qp.ubx[:] = f1 + self._umax
        self._v_land_now = _STANDSTILL_LANDING * self._v_land if hold else self._v_land
        if hold and self._land is None and side == -sig:  # at rest on the other flank: that flank now holds it
            self._flank = sig = side
        if hold and sig * tau >= 0.0:  # no load torque presses the load onto this flank: hold the load where it
            # is unless this flank can push it towards the reference (it cannot pull, nor let a load torque bring
            # the load back)
            theta2 = self._load_estimate(z)[0]
            if sig * (origin - theta2) < 0.0:
                p[6:6 + n] = theta2 - origin
        if (hold and abs(tau) < _HANDS_OFF_TORQUE * self._ratio * self._umax
                and abs(self._u) <= _HANDS_OFF_LET_GO * self._umax):
            # holding, no load torque to hold against and the plan has let go: no torque (see *Standstill*)
            self._land = None
            qp.x[:] = 0.0
            qp.lam_x[:] = 0.0
            status, solve_time = "ok", 0.0
        elif self._rigid:  # backlash-free: the rigid-train QP alone (no flank, no crossing, no landing)
            key = self._all_contact
            status, solve_time, _ = self._solve(key, 0.0, 1)
        elif side != 0 and side == sig:  # in contact on the target flank: stay, or cross if that is cheaper
            self._land = None
            key = self._all_contact
            status, solve_time, _ = self._solve(key, sig * self._flanks[sig > 0], sig)
            lam = qp.lam_a[:n]
            if status == "ok" and not hold and lam.any():  # active-set solvers give exact zeros for inactive rows
                la = np.abs(lam)
                binding = np.flatnonzero(la > 1e-9 * (1.0 + la.max()))
                if binding.size:
                    cost = self._full_cost(key)
                    a = max(int(binding[0]) - self.n_lead, 0)
                    cross = (a, min(a + self.n_cross, n + 1))
                    self._set_aside()
                    st2, dt, cost2 = self._solve(cross, -sig * self._flanks[sig < 0], sig, True)
                    solve_time += dt
                    if st2 == "ok" and cost2 < cost - _CROSS_MARGIN * abs(cost):
                        key = cross
                        if a == 0:  # the crossing starts now
                            self._flank, self._land = -sig, cross[1]
                    else:
                        self._restore()
        else:  # floating or on the other flank: land on the target flank, or on the other if much cheaper
            if self._land is None and side == -sig:  # still on the old flank: the crossing just decided
                self._land = self.n_cross
            # a countdown only decreases (the plan may not postpone its landing); a new landing is planned with
            # a quarter of the torque limit, and never in less than two samples (accelerate, then decelerate)
            if hold and side == 0 and self._land is None:  # at rest, floating (see _holding)
                e, v = n + 1, float(z[3])
                if v != 0.0:  # the flank the gap closes on by itself, and when (else: wait)
                    fl = 1 if v > 0.0 else -1
                    e = max(1, _samples((fl * self._flanks[fl > 0] - s) / (v * self.Ts), n + 1))
                    if e <= n:
                        self._flank = sig = fl
            else:
                e = max(self._land, 1) if self._land is not None else max(self._steps_to_land(s, sig), 2)
            status, solve_time, cost, key = self._land_on(sig, e, s)
            if side == -sig and not hold:  # the crossing has not left the old flank: staying there may be cheaper
                # now (a load torque pressing the load onto it: the crossing would never happen; see *Crossings*)
                self._set_aside()
                st2, dt, cost2 = self._solve(self._all_contact, side * self._flanks[side > 0], side, True)
                solve_time += dt
                if st2 == "ok" and (status != "ok" or cost2 < cost - _CROSS_MARGIN * abs(cost)):
                    status, key, self._flank, sig = st2, self._all_contact, side, side
                else:
                    self._restore()
            if side == 0 and not hold:
                self._set_aside()
                e2 = max(self._steps_to_land(s, -sig), 2)
                st2, dt, cost2, key2 = self._land_on(-sig, e2, s)
                solve_time += dt
                if st2 == "ok" and (status != "ok" or cost2 < cost - _FLIP_MARGIN * abs(cost)):
                    status, key, self._flank = st2, key2, -sig
                    self._land = key2[1]
                else:
                    self._restore()
            if key == self._all_contact:  # the crossing given up: in contact on the old flank
                self._land = None
            elif status == "ok":  # the landing actually planned (it may have been put off), counted down from now
                self._land = key[1] if key[1] <= n or not hold else None  # waiting at rest is not a landing
        self.solve_times.append(solve_time)
        if self._k in self.inject_failures:
            status = "injected failure"
        self.statuses.append(status)
        reason = None
        overran = solve_time > self.settings.max_solve_time
        if overran:  # counted whatever the solve's status (a failed solve that overran overran too: before, it was
            self.overruns += 1  # left out, and overruns fell short of the steps over the budget in solve_times)
        if status != "ok":
            reason = f"solve failed: {status}"
        elif overran:
            if self.realtime:  # as on the target; off by default so simulations are deterministic
                reason = (f"solve overran: {solve_time * 1e6:.3g} us > max_solve_time "
                          f"{self.settings.max_solve_time * 1e6:.3g} us")
        if reason is None:
            self._plan[:] = qp.x
            self._lam[:] = qp.lam_x
            u = _clip_torque(float(qp.x[0]) - f1, self._umax)  # the QP's bound holds to rounding: clip
            if note is not None:  # a reading missing or rejected: the plan ran on the prediction
                self.fallbacks.append({"t": float(t), "reason": note})
        else:  # the previous plan's next input, saturated; a late plan still warm-starts the next one
            u = _clip_torque(float(qp.x0[0]) - f1, self._umax)
            self.fallbacks.append({"t": float(t), "reason": reason if note is None else f"{reason}; {note}"})
            if status == "ok":
                self._plan[:] = qp.x
                self._lam[:] = qp.lam_x
            else:
                self._plan[:] = qp.x0
                self._lam[:] = 0.0
            self._plan[0] = u + f1
        self._u = u
        self._k += 1
        if self._land is not None:
            self._land -= 1
        self.step_times.append(time.perf_counter() - t_step)
        return u

    def describe(self) -> dict[str, Any]:
        """Settings for reports: horizon, solver and how it is called, weights, crossing length."""
        d = dataclasses.asdict(self.settings)
        return {"name": self.name, "kind": "mpc", "Ts": self.Ts, "preview": self.preview, **d,
                "qp_solver": self._qp.plugin, "compiled": self._qp.compiled, "solver_note": self._qp.note,
                "crossing_samples": self.n_cross, "patterns": len(self._patterns),
                "governor": ({"acceleration": self._a_gov, "max_speed": self._v_gov if math.isfinite(self._v_gov)
                              else None, "jump": self._dp_pass, "speed_lead": self._dv_pass}
                             if self._gov_on else None),
                "gap_model": "rigid" if self._rigid else "gap", "rigid_reason": self.rigid_reason,
                "design_notes": list(self.design_notes)}
