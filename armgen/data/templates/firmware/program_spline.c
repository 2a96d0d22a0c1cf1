{$first_map, $maps, $first_knot, $knots}
