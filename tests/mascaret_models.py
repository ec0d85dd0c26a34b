"""A small Mascaret model written for the tests: three reaches meeting at a confluence, every kind of input.

Reaches ``amont1`` (0-250 m) and ``amont2`` (0-200 m) join reach ``aval`` (0-1000 m) at node 1. Free ends:
``up1`` (a hydrograph in hours), ``up2`` (a constant hydrograph), ``down`` (a rating Q = f(Z) that starts above
0 m³/s). Profiles with and without a major bed, one closed by survey walls at 999 m, georeferenced axis points
on ``amont1``. Four friction zones (two on ``aval``), a point inflow and an inflow over 100 m, two output sites,
one weir (which the import refuses), the grid by ranges of profiles (method 5).
"""

from __future__ import annotations

from pathlib import Path

#: Bed levels of the profiles, m: reach → [(name, abscissa m, bed level m, with a major bed)].
PROFILES = {
    "amont1": [("P1a", 0.0, 12.0, False), ("P1b", 100.0, 11.6, True), ("P1c", 250.0, 11.0, False)],
    "amont2": [("P2a", 0.0, 11.8, False), ("P2b", 200.0, 11.0, False)],
    "aval": [("P3a", 0.0, 11.0, True), ("P3b", 300.0, 10.4, True), ("P3c", 600.0, 9.8, False),
             ("P3d", 1000.0, 8.8, False)],
}
#: Survey of a profile with a major bed: (y m, height above the bed m, bed mark).
MAJOR = [(0.0, 3.0, "T"), (5.0, 1.0, "T"), (7.0, 0.8, "B"), (9.0, 0.0, "B"), (11.0, 0.8, "B"), (13.0, 1.0, "T"),
         (18.0, 3.0, "T")]
#: Survey of a profile of the minor bed only.
MINOR = [(0.0, 2.0, "B"), (2.0, 0.0, "B"), (6.0, 0.0, "B"), (8.0, 2.0, "B")]
#: Axis points of the georeferenced reach amont1 (map x, y, m).
AXIS = {"P1a": (1000.0, 5000.0), "P1b": (1080.0, 4940.0), "P1c": (1200.0, 4850.0)}

LAWS = {
    "hydro.loi": "# up1: a hydrograph in hours\n# t Q\n H\n 0.0 1.0\n 1.0 2.0\n 10.0 2.0\n",
    "const.loi": "# up2\n S\n 0.0 0.5\n 86400.0 0.5\n",
    "rating.loi": "# down: Q = f(Z)\n# Z Q\n 9.0 0.5\n 9.5 2.0\n 10.5 8.0\n",
    "lat.loi": "# point inflow\n S\n 0.0 0.2\n 36000.0 0.4\n",
    "linlat.loi": "# inflow over a length, m3/s per m\n S\n 0.0 0.001\n 36000.0 0.001\n",
}


def geometry_text() -> str:
    lines = ["# test geometry (LIDO 3.0)"]
    for reach, profiles in PROFILES.items():
        for name, x, bed, major in profiles:
            header = f"PROFIL {reach} {name} {x}"
            if reach == "amont1":
                ax, ay = AXIS[name]
                header += f" {ax - 9} {ay - 9} {ax + 9} {ay + 9} AXE {ax} {ay}"
            lines.append(header)
            survey = MAJOR if major else MINOR
            if name == "P3a":  # the survey's closing walls
                lines.append(f"0.0 999.0 {survey[0][2]}")
            for y, h, mark in survey:
                lines.append(f"{y} {bed + h:.3f} {mark}")
            if name == "P3a":
                lines.append(f"{survey[-1][0]} 999.0 {survey[-1][2]}")
    return "\n".join(lines) + "\n"


XCAS = """<?xml version="1.0" encoding="ISO-8859-1"?>
<!DOCTYPE fichierCas SYSTEM "mascaret-1.0.dtd">
<fichierCas>
  <parametresCas>
    <parametresGeneraux>
      <code>3</code>
      <presenceCasiers>false</presenceCasiers>
    </parametresGeneraux>
    <parametresModelePhysique>
      <perteChargeConf>false</perteChargeConf>
      <compositionLits>1</compositionLits>
      <conservFrotVertical>false</conservFrotVertical>
      <interpolLinStrickler>false</interpolLinStrickler>
    </parametresModelePhysique>
    <parametresNumeriques>
      <calcOndeSubmersion>false</calcOndeSubmersion>
      <hauteurEauMini>0.01</hauteurEauMini>
    </parametresNumeriques>
    <parametresTemporels>
      <pasTemps>30.0</pasTemps>
      <tempsInit>0.0</tempsInit>
      <critereArret>1</critereArret>
      <nbPasTemps>1000</nbPasTemps>
      <tempsMax>36000.0</tempsMax>
      <pasTempsVar>false</pasTempsVar>
      <nbCourant>0.8</nbCourant>
    </parametresTemporels>
    <parametresGeometrieReseau>
      <geometrie>
        <fichier>model.georef</fichier>
        <format>2</format>
        <profilsAbscAbsolu>false</profilsAbscAbsolu>
      </geometrie>
      <listeBranches>
        <nb>3</nb>
        <numeros>1 2 3</numeros>
        <abscDebut>0.0 0.0 0.0</abscDebut>
        <abscFin>250.0 200.0 1000.0</abscFin>
        <numExtremDebut>1 3 5</numExtremDebut>
        <numExtremFin>2 4 6</numExtremFin>
      </listeBranches>
      <listeNoeuds>
        <nb>1</nb>
        <noeuds>
          <noeud>
            <num>2 4 5 0 0</num>
          </noeud>
        </noeuds>
      </listeNoeuds>
      <extrLibres>
        <nb>3</nb>
        <num>1 2 3</num>
        <numExtrem>1 3 6</numExtrem>
        <noms>
          <string>up1</string>
          <string>up2</string>
          <string>down</string>
        </noms>
        <typeCond>1 1 4</typeCond>
        <numLoi>1 2 3</numLoi>
      </extrLibres>
    </parametresGeometrieReseau>
    <parametresConfluents>
      <nbConfluents>0</nbConfluents>
    </parametresConfluents>
    <parametresPlanimetrageMaillage>
      <methodeMaillage>5</methodeMaillage>
      <planim>
        <nbPas>100</nbPas>
        <nbZones>1</nbZones>
        <valeursPas>0.1</valeursPas>
        <num1erProf>1</num1erProf>
        <numDerProf>9</numDerProf>
      </planim>
      <maillage>
        <modeSaisie>2</modeSaisie>
        <maillageClavier>
          <nbSections>0</nbSections>
          <nbPlages>3</nbPlages>
          <num1erProfPlage>1 4 6</num1erProfPlage>
          <numDerProfPlage>3 5 9</numDerProfPlage>
          <pasEspacePlage>40.0 60.0 100.0</pasEspacePlage>
          <nbZones>0</nbZones>
        </maillageClavier>
      </maillage>
    </parametresPlanimetrageMaillage>
    <parametresSingularite>
      <nbSeuils>1</nbSeuils>
      <seuils>
        <structureParametresSeuil>
          <nom>barrage1</nom>
          <type>2</type>
          <numBranche>3</numBranche>
          <abscisse>700.0</abscisse>
        </structureParametresSeuil>
      </seuils>
    </parametresSingularite>
    <parametresApportDeversoirs>
      <debitsApports>
        <nbQApport>2</nbQApport>
        <noms>
          <string>point inflow</string>
          <string>bank inflow</string>
        </noms>
        <numBranche>3 3</numBranche>
        <abscisses>150.0 400.0</abscisses>
        <longueurs>0.0 100.0</longueurs>
        <numLoi>4 5</numLoi>
      </debitsApports>
    </parametresApportDeversoirs>
    <parametresCalage>
      <frottement>
        <loi>1</loi>
        <nbZone>4</nbZone>
        <numBranche>1 2 3 3</numBranche>
        <absDebZone>0.0 0.0 0.0 500.0</absDebZone>
        <absFinZone>250.0 200.0 500.0 1000.0</absFinZone>
        <coefLitMin>25.0 30.0 35.0 28.0</coefLitMin>
        <coefLitMaj>15.0 20.0 12.0 10.0</coefLitMaj>
      </frottement>
      <zoneStockage>
        <nbProfils>0</nbProfils>
      </zoneStockage>
    </parametresCalage>
    <parametresLoisHydrauliques>
      <nb>5</nb>
      <lois>
        <structureParametresLoi>
          <nom>hydro</nom>
          <type>1</type>
          <donnees><modeEntree>1</modeEntree><fichier>hydro.loi</fichier></donnees>
        </structureParametresLoi>
        <structureParametresLoi>
          <nom>const</nom>
          <type>1</type>
          <donnees><modeEntree>1</modeEntree><fichier>const.loi</fichier></donnees>
        </structureParametresLoi>
        <structureParametresLoi>
          <nom>rating</nom>
          <type>5</type>
          <donnees><modeEntree>1</modeEntree><fichier>rating.loi</fichier></donnees>
        </structureParametresLoi>
        <structureParametresLoi>
          <nom>lat</nom>
          <type>1</type>
          <donnees><modeEntree>1</modeEntree><fichier>lat.loi</fichier></donnees>
        </structureParametresLoi>
        <structureParametresLoi>
          <nom>linlat</nom>
          <type>1</type>
          <donnees><modeEntree>1</modeEntree><fichier>linlat.loi</fichier></donnees>
        </structureParametresLoi>
      </lois>
    </parametresLoisHydrauliques>
    <parametresConditionsInitiales>
      <repriseEtude><repriseCalcul>false</repriseCalcul></repriseEtude>
      <ligneEau><LigEauInit>false</LigEauInit></ligneEau>
    </parametresConditionsInitiales>
    <parametresImpressionResultats>
      <pasStockage>
        <premPasTpsStock>1</premPasTpsStock>
        <pasStock>10</pasStock>
      </pasStockage>
      <stockage>
        <option>2</option>
        <nbSite>2</nbSite>
        <branche>1 3</branche>
        <abscisse>50.0 900.0</abscisse>
      </stockage>
    </parametresImpressionResultats>
  </parametresCas>
</fichierCas>
"""


def write_model(folder: Path, *, xcas: str | None = None) -> Path:
    """Write the model into ``folder``; returns the ``.xcas`` path. ``xcas`` replaces the case file's text."""
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "model.georef").write_text(geometry_text(), encoding="utf-8")
    for name, text in LAWS.items():
        (folder / name).write_text(text, encoding="utf-8")
    path = folder / "model.xcas"
    path.write_text(xcas if xcas is not None else XCAS, encoding="latin-1")
    return path
