"""Plan-then-verify (thesis Alg. 2, Eqs. 4.5–4.7): check an arm trajectory against the wrist
(``verifier``); the ``articutool verify`` command (``cli``)."""
