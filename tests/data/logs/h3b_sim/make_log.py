"""Write interpolation_error_b3um.csv: helper h3's own rig simulator (rig.c + rigsim.py, not gearctl's code).

shing1993_servo_friction's gears, true b = 3 um, Coulomb 0.2 N m on the load (LuGre bristles, no Stribeck rise),
Hunt-Crossley contact, a 0.1 ms current loop, PID + feedforward on the motor encoder over random moves with dwells,
1 kHz, 2^22-count encoders whose readings carry a sine/cosine interpolation error of 1 % of a line (2048 lines on
the motor, 4096 on the load: 0.58 and 1.15 um along the line of action). Before the fix gearctl identify gave b
4.12 um, 95 % interval 3.42-4.82 um. Run (with gearctl importable): gcc -O2 -shared -fPIC -o librig.so rig.c -lm;
python make_log.py
"""
from rigsim import Setup, model_info, simulate, truth_from_model, write_csv

MODEL = "shing1993_servo_friction"
truth = truth_from_model(model_info(MODEL), b=3e-6, tc2=0.2, Ts_ratio1=1.0, Ts_ratio2=1.0)
setup = Setup(model=MODEL, truth=truth, fs=1000.0, duration=6.0, cpr1=1 << 22, cpr2=1 << 22, noise1=2e-7,
              noise2=2e-7, amp=0.05, seed=3, extra={"interp": 0.01})
log = simulate(setup)
write_csv("interpolation_error_b3um.csv", log, comments=(
    "h3's rig simulator (tests/data/logs/h3b_sim/make_log.py): shing1993_servo_friction gears, true b = 3e-6 m,",
    "2^22-count encoders with a 1 % interpolation error (2048 / 4096 lines), 1 kHz, PID on the motor encoder"),
    fmt="%.10g")

# speed_up_lugre.csv: a speed-increasing pair (speed_up_rig.toml, ratio 0.25), true b = 50 um, LuGre friction on the
# load (0.02 N m, bristles 5 urad, their damping critical on the load's inertia), 1 kHz. identify gave J1 +7.3 %,
# J2 -13.8 %, a motor Coulomb friction of 7.4 mN m (truth 0) and the load's 9 % low, all outside their intervals
# and not flagged (open; with a tanh law instead of LuGre the gap gate names J1, J2 and the motor's friction)
RIG = "speed_up_rig.toml"
truth = truth_from_model(model_info(RIG), b=5e-5, tc2=0.02, d1=1e-4, d2=2e-3, Ts_ratio1=1.0, Ts_ratio2=1.0)
setup = Setup(model=RIG, truth=truth, duration=6.0, amp=0.4, umax=5.0, seed=11)
write_csv("speed_up_lugre.csv", simulate(setup), comments=(
    "h3's rig simulator (tests/data/logs/h3b_sim/make_log.py): speed_up_rig.toml, true b = 5e-5 m, J1 0.0070185,",
    "J2 0.0002196 kg m^2, viscous 1e-4 and 2e-3 N m s/rad, LuGre Coulomb 0 and 0.02 N m, 1 kHz, 2^17/2^19 counts"),
    fmt="%.10g")
