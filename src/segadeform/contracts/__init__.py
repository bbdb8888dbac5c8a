"""The model package contract (:mod:`.model_package`): what export writes and every runtime reads."""
