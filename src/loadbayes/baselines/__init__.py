"""Estimators to compare against: least squares and the Kalman filter."""
