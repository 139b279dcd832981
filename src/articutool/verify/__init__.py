"""Plan-then-verify (thesis Alg. 2)."""
