"""Error classes (spec §9.2, Table 9-1)."""

# Table 9-1 class names, exact spelling.
ERROR_CLASSES = (
    "SignatureMismatch", "Truncated", "UnsupportedMajorVersion", "UnsupportedMinorVersion",
    "ReservedBitsSet", "ChunkTagInvalid", "ChunkLengthPastEnd", "ChunkCrcMismatch",
    "ChunkOrder", "UnknownCriticalChunk", "TrailingData", "FieldOutOfRange",
    "DecodedSizeMismatch", "LimitExceeded", "ChunkSizeMismatch", "UnknownCodingMethod",
    "PaddingBitsSet", "CoordinateOutOfRange", "AnsStreamInvalid", "EscapeOverflow",
    "ScaleIndexOutOfRange", "LatticeDimension", "RateNotCoded", "LatticeSearchFailed",
    "TileOrder", "TileBoxMismatch", "OctreeInvalid", "FitFailed", "NonFiniteValue",
    "ValueNotPositive", "ValueInvalid", "BasisSingular", "BasisIllConditioned",
    "BasisNotOrthogonal", "InterchangeFormat", "TensorMissing", "TensorUnexpected",
    "TensorDtype", "TensorRank", "TensorShape", "PlyHeaderInvalid", "PlyPropertyMissing",
    "PlyShCoefficients", "PlyTruncated", "PlyValueNotFinite", "NeuralGaussiansUnsupported",
    "RenderSettingInvalid", "UnsupportedInput", "Io",
)


class SalvqError(Exception):
    """A stream error: `error_class` is a Table 9-1 class name, `message` says what broke."""

    def __init__(self, error_class: str, message: str):
        if error_class not in ERROR_CLASSES:
            raise ValueError(f"unknown error class {error_class!r}")
        super().__init__(f"{error_class}: {message}")
        self.error_class = error_class
        self.message = message

    def __str__(self) -> str:  # pragma: no cover - trivial
        return f"error[{self.error_class}]: {self.message}"
