  probe = probe + ($value * ${P}_LIT(0.0));
