%
(ISO 230-4 circular test: diameter 50 mm, F3000 mm/min, ccw)
(lead-in 90 deg, measured circle 360 deg, lead-out 90 deg, centre X0 Y0)
N10 G21 G17 G90 G94 G40 G49 G80
N20 G00 X0.0 Y-25.0
N30 G03 X25.0 Y0.0 I0.0 J25.0 F3000 (lead-in)
N40 G03 X25.0 Y0.0 I-25.0 J0.0 (measured circle)
N50 G03 X0.0 Y25.0 I-25.0 J0.0 (lead-out)
N60 M30
%
