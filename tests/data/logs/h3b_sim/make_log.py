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
