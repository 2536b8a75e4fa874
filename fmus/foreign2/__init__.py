"""Second foreign-plant pair (issue 20): Foreign2ZStage (FMI 2.0 CS) and Foreign2BallScrew
(FMI 3.0 CS), written apart from fmus/ and fmus/foreign/; built by :mod:`drillcosim.fmus.foreign2.build`."""
