"""Generate: graph → MJCF writer (MjSpec), physical rules, MuJoCo validation, sampling."""
