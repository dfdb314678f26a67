// placeholder: delete once the module has real sources
