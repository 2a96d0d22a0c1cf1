{$u, $w, $slope}
