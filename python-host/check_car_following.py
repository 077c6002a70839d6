#!/usr/bin/env python3
"""Facts about SUMO's car-following models, read from the installed SUMO (not from our table).

The Rust table in crates/syncroad-control/src/drive/car_following/models.rs embeds the output of this script
in its tests, so an upgrade of SUMO that changes a fact makes those tests worth re-running:

    .venv/bin/python python-host/check_car_following.py

prints JSON with
* "version": SUMO's version string;
* "vtype_attributes": every attribute of <vType> in SUMO's own schema
  (data/xsd/types/route.xsd, complexType vTypeBaseType);
* "models_loaded": the carFollowModel values SUMO loads (a vType with that model and a
  vehicle-free network start without error);
* "sigma_applied": the models for which a vType's sigma reaches the simulation
  (libsumo.vehicletype.getImperfection returns it; SUMO silently ignores sigma elsewhere);
* "accel_applied": the same for accel (W99 ignores it).
"""
import json
import os
import re
import sys
import tempfile

import libsumo as ls
import sumo

HERE = os.path.dirname(os.path.abspath(__file__))
NET = os.path.join(HERE, "..", "sumo-nets", "sugiyama-ring.net.xml")
CANDIDATES = ["Krauss", "KraussOrig1", "KraussPS", "KraussX", "SmartSK", "Daniel1",
              "PWagner2009", "BKerner", "IDM", "IDMM", "EIDM", "Wiedemann", "W99", "ACC", "CACC",
              "KraussAB", "Rail"]


def vtype_attributes():
    xsd = os.path.join(sumo.SUMO_HOME, "data", "xsd", "types", "route.xsd")
    text = open(xsd).read()
    block = re.search(r'<xsd:complexType name="vTypeBaseType">(.*?)</xsd:complexType>', text, re.S)
    return sorted(set(re.findall(r'<xsd:attribute name="([^"]+)"', block.group(1))))


def probe(model, tmp):
    rou = os.path.join(tmp, "probe.rou.xml")
    with open(rou, "w") as f:
        f.write('<routes><vType id="t" carFollowModel="%s" sigma="0.37" accel="1.7"/></routes>\n'
                % model)
    try:
        ls.start(["sumo", "-n", NET, "-r", rou, "--no-step-log", "true", "--no-warnings", "true",
                  "--step-length", "0.1"])
    except Exception:
        return None
    try:
        return ls.vehicletype.getImperfection("t"), ls.vehicletype.getAccel("t")
    finally:
        ls.close()


def main():
    tmp = tempfile.mkdtemp(prefix="cfcheck-")
    loaded, sigma, accel = [], [], []
    for m in CANDIDATES:
        r = probe(m, tmp)
        if r is None:
            continue
        loaded.append(m)
        if abs(r[0] - 0.37) < 1e-9:
            sigma.append(m)
        if abs(r[1] - 1.7) < 1e-9:
            accel.append(m)
    ls.start(["sumo", "-n", NET, "--no-step-log", "true"])
    version = ls.getVersion()[1]
    ls.close()
    json.dump({"version": version, "vtype_attributes": vtype_attributes(),
               "models_loaded": loaded, "sigma_applied": sigma, "accel_applied": accel},
              sys.stdout, indent=1)
    print()


if __name__ == "__main__":
    main()
