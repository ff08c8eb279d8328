"""The rover's state estimator: an EKF over GPS, gyro and wheel odometry, in local ENU metres.

``estimator.estimator.Estimator`` is the front end the onboard loop calls; ``estimator.ekf.RoverEkf`` the
filter; ``estimator.geodesy`` WGS84 <-> ENU; ``estimator.config.EstimatorConfig`` its settings.
"""
