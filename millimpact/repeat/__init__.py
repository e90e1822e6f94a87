"""Repeated impacts at one spot: each impact starts from the previous one's residual state
(plastic strain, hardening, residual stress, the dent); shakedown or ratcheting (DESIGN.md 10)."""
