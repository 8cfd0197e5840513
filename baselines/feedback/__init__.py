"""Feedback controllers: each axis closes its loop on the measured error, no model of the reference's future.

- :mod:`.qft`: robust QFT G(s) with pre-filter F(s), Jahanpour et al. (2014), section 2c;
- :mod:`.smc`: adaptive sliding-mode control, Altintas, Erkorkmaz and Zhu (2000), Jahanpour et al.'s Table 2;
- :mod:`.fuzzy`: Mamdani fuzzy controller, Jahanpour et al.'s Table 1;
- :mod:`.pi_imc_hinf` / :mod:`.pi_imc_hinf_policies`: Yadav, Pathak and Gaur (2020)'s robust PI, IMC and
  H-infinity designs for the CNCMT axis;
- :mod:`.nctf`: fuzzy nominal-characteristic-trajectory-following control, Purtojo et al.

A new feedback controller is one module here plus a line in :mod:`vcnc_baselines.registry`.
"""
