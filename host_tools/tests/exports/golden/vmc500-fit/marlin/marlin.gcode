; abbe export marlin: skew (M852) and backlash (M425); M500 stores them
G21 ; millimetres: M852 and M425 read linear units
M852 I0.000001033 J-0.000000587 K-0.000003560
M425 F1.0 S1.000 X0.0020 Y0.0025 Z0.0020
