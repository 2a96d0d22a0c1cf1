  for (entry = 0; entry < $count; ++entry) { probe = probe + (${array}[entry] * ${P}_LIT(0.0)); }
