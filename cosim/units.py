"""Unit conversion factors to SI, used at the boundary (scenario files, records, printouts)."""
INCH = 0.0254                 # m
FOOT = 0.3048                 # m
POUND_FORCE = 4.4482216152605  # N
PSI = POUND_FORCE / INCH**2   # Pa
POUND_MASS = 0.45359237       # kg
SLUG = POUND_FORCE / FOOT     # kg (lbf s^2 / ft)
RPM = 2.0 * 3.141592653589793 / 60.0  # rad/s
