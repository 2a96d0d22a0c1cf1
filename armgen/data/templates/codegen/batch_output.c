${p}_real *out$k
