"""Commissioning a machine: an identification experiment on it, design rules from what it measured, the record.

- :mod:`.identify`: the experiment (a PRBS around a low-gain loop, slow reversal moves), the frequency-response
  estimate and the fit of the rigid body, the first mode, the dead time and the Coulomb levels;
- :mod:`.design`: the rules that turn an identified model into the servo law's gains and filters;
- :mod:`.record`: the record (JSON, printing, plot) and the two ways to commission (nominal, per machine).
"""
