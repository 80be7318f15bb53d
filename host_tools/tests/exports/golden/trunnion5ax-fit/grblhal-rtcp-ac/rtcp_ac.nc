; abbe export grblhal-rtcp-ac: identified A/C centres for grblHAL's rtcp_ac (kinematics/rtcp_ac.c, experimental), mm
; model: model_five.bin; nominal from machine.toml
; send each line to the controller (or paste into a sender); then set the work offset and issue M852 as rtcp_ac requires
; RTCP A offset X: nominal 0.000, change 21.0 um
$640=0.021
; RTCP A offset Y: nominal 25.000, change -16.0 um
$641=24.984
; RTCP A offset Z: nominal -440.000, change 5.0 um
$642=-439.995
; RTCP C offset X: nominal 0.000, change 0.0 um
$643=0.000
; RTCP C offset Y: nominal -25.000, change 16.0 um
$644=-24.984
; RTCP C offset Z: nominal 90.000, change -5.0 um
$645=89.995
