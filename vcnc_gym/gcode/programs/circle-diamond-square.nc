%
(NAS 979 / ISO 10791-7 circle-diamond-square: square 60 mm, F6000 mm/min)
N10 G21 G17 G90 G94 G40
N20 G00 X-30.0 Y-30.0
N30 G01 X30.0 Y-30.0 F6000 (square)
N40 X30.0 Y30.0
N50 X-30.0 Y30.0
N60 X-30.0 Y-30.0
N70 X0.0 Y-27.0 (link to the diamond)
N80 X27.0 Y0.0 (diamond)
N90 X0.0 Y27.0
N100 X-27.0 Y0.0
N110 X0.0 Y-27.0
N120 X0 Y-18.0 (link to the circle)
N130 G03 X0 Y-18.0 I0 J18.0 (circle)
N140 M30
%
