{$control, $differences, $quaternion, $rotvec, $omega, $first_map, $maps}
