    if (current[$stop] != ${P}_LIT(0.0)) { break; }  /* finished: the rest are the identity */
