"""Plan-then-verify (thesis Alg. 2, Eqs. 4.5–4.7): check an arm trajectory against the wrist."""

from articutool.verify.verifier import VerificationReport, densify, verify_trajectory

__all__ = ["VerificationReport", "densify", "verify_trajectory"]
