  ${p}_real probe = ${P}_LIT(0.0);
