${P}_LIT($value)
