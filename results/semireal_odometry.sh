# The drifting odometries of the semi-real logs (`crlam semireal` flags), shared by the scripts
# of results/odometry_noise and results/loop_closing: "good", an odometry of about 0.5-1 % error
# per metre (a well-calibrated robot: the unseen 1.4 km hospital log's odometry ends 11 m from its
# start); "mild", twice its noise and five times its heading bias. Sourced, not run.
good="--trans-scale 0.005 --trans-noise 0.005 --rot-scale 0.005 --heading-bias 0.0002 --rot-noise 0.005 --rot-per-trans 0.001 --turn-slip 0.01 --seed 2"
mild="--trans-scale 0.01 --trans-noise 0.01 --rot-scale 0.01 --heading-bias 0.001 --rot-noise 0.01 --rot-per-trans 0.002 --turn-slip 0.03 --seed 1"
