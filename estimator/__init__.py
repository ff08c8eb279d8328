"""The rover's state estimator: an EKF over GPS, gyro, AHRS heading and wheel odometry, in local ENU metres.

``estimator.estimator.Estimator`` is the front end the onboard loop calls; ``estimator.ekf.RoverEkf`` the
filter (arithmetic compiled in ``estimator.ekf_kernels``); ``estimator.health.EstimatorHealth`` its health
flags; ``estimator.geodesy`` WGS84 <-> ENU; ``estimator.config.EstimatorConfig`` its settings. See
docs/estimator.md.
"""
